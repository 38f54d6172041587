"""The data of a study report: a study's renders as its SQLite database records them
(study_results), grouped by sweep position over seeds. Part of aliquot_report.py.
"""
import json
import sqlite3

import numpy as np

from bias_table import BIAS, DENOISED_BIAS

METRICS = ["mean_abs", "rmse", "relative_mse", "max_bucket", "p99_bucket"]
# After Open Image Denoise, for a study with "denoise" (NaN for any other).
DENOISED = ["denoised_mean_abs", "denoised_rmse", "denoised_relative_mse"]


class Render:
    """One study render (one key): its spec and what it measured."""

    def __init__(self, row):
        self.key = row["render_key"]
        self.group, index, seed = self.key.rsplit("/", 2)
        self.index, self.seed = int(index), int(seed)
        spec = json.loads(row["spec_json"])
        self.scene, self.width, self.height = spec["scene"], spec["width"], spec["height"]
        self.strategy = spec["strategy"]
        self.method = self.strategy["method"]
        self.samples, self.rays = row["samples"], row["rays"]
        self.seconds, self.sps = row["seconds"], row["samples_per_second"]
        for m in METRICS:
            v = row[m]
            setattr(self, m, float("nan") if v is None else v)
        for m in DENOISED + BIAS + DENOISED_BIAS:  # older databases lack these columns
            v = row[m] if m in row.keys() else None
            setattr(self, m, float("nan") if v is None else v)
        self.outcome = json.loads(row["outcome_json"] or "{}")
        self.render_id = row["render_id"]
        self.origin = row["origin"]

    @property
    def pixels(self):
        return self.width * self.height


class Point:
    """The renders of one group at one sweep position, over their seeds."""

    def __init__(self, renders):
        self.renders = sorted(renders, key=lambda r: r.seed)
        self.first = self.renders[0]
        self.n = len(self.renders)

    def mean(self, attr):
        return float(np.mean([getattr(r, attr) for r in self.renders]))

    def sd(self, attr):
        vals = [getattr(r, attr) for r in self.renders]
        return float(np.std(vals, ddof=1)) if len(vals) > 1 else 0.0

    def param(self, name):
        if name == "method":
            return self.first.method
        if name == "seed":
            return ",".join(str(r.seed) for r in self.renders)
        return self.first.strategy.get(name)


class Study:
    def __init__(self, db, study_id):
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
        con.row_factory = sqlite3.Row
        row = con.execute("SELECT * FROM studies WHERE id = ?", (study_id,)).fetchone()
        if row is None:
            raise SystemExit(f"aliquot report: no study {study_id!r} in {db}")
        stored = json.loads(row["definition_json"])
        self.id = study_id
        self.definition = stored["definition"]
        self.scale = stored["scale"]
        self.study_file = stored.get("study_file", "")
        rows = con.execute(
            "SELECT * FROM study_results WHERE study_id = ? AND state = 'done' ORDER BY rowid",
            (study_id,),
        ).fetchall()
        self.renders = [Render(r) for r in rows]
        self.groups = {}
        for r in self.renders:
            self.groups.setdefault(r.group, {}).setdefault(r.index, []).append(r)
        con.close()
        self.group_defs = {g["name"]: g for g in self.definition["renders"]}

    def points(self, group):
        """The group's sweep positions in order, each over its seeds."""
        by_index = self.groups.get(group, {})
        return [Point(by_index[i]) for i in sorted(by_index)]

    def method(self, group):
        pts = self.points(group)
        return pts[0].first.method if pts else self.group_defs[group]["method"]

    def label(self, group, groups):
        """The method name, or the group name where two groups share a method."""
        m = self.method(group)
        if sum(1 for g in groups if self.method(g) == m) > 1:
            return group
        return m
