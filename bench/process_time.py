#!/usr/bin/env python3
"""What `aliquot render` costs beyond its render: the whole process's wall time beside
the render time it reports, for one binary or several interleaved (before and after).

  python3 bench/process_time.py [--aliquot build/bin/aliquot [OTHER ...]]
        [--cases 2048x2048:1 1024x1024:4] [--scene cornell-box] [--threads 2] [--repeat 3]
        [--out-dir build/process-time]

Issue 31: 2048x2048 at 1 spp reported 1.86 s of rendering and took 4.0 s as a process
(a 43 MB ZIP EXR); 1024x1024 at 4 spp 1.45 s against 2.42 s. Each round runs every case
with every binary in turn, so a change of the machine's load hits them alike. Per binary
and case: the render seconds the CLI reports, the process's seconds (start to exit: the
scene, the buffers, the render, the EXR written, the memory given back), and their
difference; the best run of each and every run. The binaries' EXRs of a case must be the
same bytes (a change of how the EXR is written must not change it): a difference is
reported, and the exit status is 1.

Printed: JSON on stdout; a Markdown table on stderr.
"""

import argparse
import filecmp
import json
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import peers_speed as ps  # noqa: E402  (a run's JSON and wall time, as the peers bench)


def main(argv=None):
    ap = argparse.ArgumentParser(description="aliquot render: process time beside render time.")
    ap.add_argument("--aliquot", nargs="+", default=[os.path.join("build", "bin", "aliquot")])
    ap.add_argument("--cases", nargs="+", default=["2048x2048:1", "1024x1024:4"],
                    help="WxH:SPP ...")
    ap.add_argument("--scene", choices=ps.SCENES, default="cornell-box")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "build", "process-time"))
    args = ap.parse_args(argv)
    if args.repeat < 1 or args.threads < 1:
        ap.error("--repeat and --threads must be positive")
    binaries = [ps.aliquot_binary(b, "process-time") for b in args.aliquot]
    cases = []
    for c in args.cases:
        res, _, spp = c.partition(":")
        if not spp.isdigit() or int(spp) < 1:
            ap.error(f"expected WxH:SPP, got {c!r}")
        cases.append((res, int(spp)))
    os.makedirs(args.out_dir, exist_ok=True)

    def out(b, res, spp):
        return os.path.join(args.out_dir, f"binary{b}-{args.scene}-{res}-{spp}spp.exr")

    runs = {(b, c): [] for b in range(len(binaries)) for c in cases}
    load_start = os.getloadavg()
    for rep in range(args.repeat):
        for res, spp in cases:
            for b, path in enumerate(binaries):
                cmd = [path, "render", "--scene", args.scene, "--resolution", res,
                       "--spp", str(spp), "--seed", "1", "--threads", str(args.threads),
                       "--json", "--out", out(b, res, spp)]
                runs[(b, (res, spp))].append(ps.run_json(
                    cmd, f"{res} {spp} spp, binary {b} ({rep + 1}/{args.repeat})"))

    results, differ = [], []
    for res, spp in cases:
        for b, path in enumerate(binaries):
            rs = runs[(b, (res, spp))]
            overhead = [r["process_seconds"] - r["seconds"] for r in rs]
            results.append({
                "binary": path, "resolution": res, "spp": spp,
                "exr_bytes": os.path.getsize(out(b, res, spp)),
                "render_seconds": [round(r["seconds"], 3) for r in rs],
                "process_seconds": [round(r["process_seconds"], 3) for r in rs],
                "render_best": min(r["seconds"] for r in rs),
                "process_best": min(r["process_seconds"] for r in rs),
                "beyond_render_median": statistics.median(overhead),
                "load_before": [r["load_before"] for r in rs]})
            if b > 0 and not filecmp.cmp(out(0, res, spp), out(b, res, spp), shallow=False):
                differ.append(f"{res} {spp} spp: binary {b}'s EXR differs from binary 0's")

    rows = ["| binary | case | render s (runs) | process s (runs) | best render / process | "
            "process - render (median) | EXR |",
            "|---|---|---|---|---|---|---|"]
    for r in results:
        rows.append(f"| {binaries.index(r['binary'])} | {r['resolution']} {r['spp']} spp | "
                    f"{' / '.join(f'{x:.2f}' for x in r['render_seconds'])} | "
                    f"{' / '.join(f'{x:.2f}' for x in r['process_seconds'])} | "
                    f"{r['render_best']:.2f} / {r['process_best']:.2f} | "
                    f"{r['beyond_render_median']:.2f} s | {r['exr_bytes'] / 1e6:.1f} MB |")
    print("\n".join(rows), file=sys.stderr)
    for d in differ:
        print(f"process-time: {d}", file=sys.stderr)
    print(json.dumps({"scene": args.scene, "threads": args.threads, "repeat": args.repeat,
                      "binaries": binaries, "results": results, "exr_differ": differ,
                      "load_start": [round(x, 2) for x in load_start],
                      "load_end": [round(x, 2) for x in os.getloadavg()],
                      "measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}, indent=2))
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
