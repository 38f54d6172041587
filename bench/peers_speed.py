#!/usr/bin/env python3
"""Speed and noise of Aliquot against its strongest CPU peers on one scene, in one run.

  python3 bench/peers_speed.py [--aliquot build/bin/aliquot] [--spp 64 256]
        [--scene cornell-box|cornell-caustics] [--resolution 256x256] [--threads 2]
        [--repeat 3] [--peers mitsuba-llvm,mitsuba-scalar,cycles] [--reference REF.exr]
        [--no-install]

Peers (each in its own process, each timing its render alone: not start-up, scene
building or writing the image; the whole process's wall time is recorded beside it,
`process_seconds`, for ours what a user waits for: loading, rendering, writing the EXR):
  mitsuba-llvm    Mitsuba 3 llvm_ad_rgb: Dr.Jit compiles the path tracer into one
                  vectorised kernel. Needs a system libLLVM 19 (Debian's libllvm19;
                  Mitsuba 3.9.1 aborts in code generation with bookworm's LLVM 14-16);
                  DRJIT_LIBLLVM_PATH is set here. A 1-spp render first, untimed, in the
                  same process, takes the JIT compilation out of the timing.
  mitsuba-scalar  Mitsuba 3 scalar_rgb (multi-threaded C++, no JIT; its slowest variant).
  cycles          Blender Cycles on the CPU through the bpy package (Blender as a Python
                  module), the same scene built by bench/cycles_cornell.py; a 1-spp
                  render first, untimed.
Scenes (--scene): cornell-box, Mitsuba's cornell_box() (our cornell-box scene), and
cornell-caustics, our scenes/cornell-caustics.json (glass and mirror spheres, a smaller
and brighter light), which tests/validation/mitsuba_scenes.py builds for Mitsuba with
analytic `sphere` shapes. Cycles renders the box only: it has no analytic sphere, and
bench/cycles_cornell.py builds the box alone, so on cornell-caustics it is skipped (said
in the output's notes). All render with a box pixel filter, paths of at most 8 segments
(our max depth 8), Russian roulette as each renderer does it.

Interleaved: for each --spp, --repeat rounds of  peer A, ours, peer B, ours, ...
so a change of machine load hits everyone alike. A renderer's speed is its best run's
samples/s (the least disturbed); every run is listed, with the load average before it.

Noise per sample: noise = mean |image - reference| over pixels and RGB, at equal spp.
The reference is --reference, else a cached Mitsuba llvm_ad_rgb render of the scene at
--reference-spp (made once under build/validation/, before any timing). Each peer's image
mean is checked against the reference's: a peer whose mean is off by more than
--mean-tolerance (0.5 % on the box, 1 % on caustics, whose fireflies make an image's mean
noisier) renders another image, so its noise ratio is flagged, not trusted.
Both noises include the reference's own residual noise equally, which pulls noise
ratios slightly towards 1.

Ratios, for each peer (ours / peer):
  speed_ratio       = best samples/s ours / best samples/s peer
  paired_ratios     = each of our runs / the peer's run just before it
  noise_ratio       = noise ours / noise peer (equal spp)
  efficiency_ratio  = speed_ratio / noise_ratio^2: how many times sooner we reach a
                      given error (Monte Carlo error ~ 1/sqrt(samples)); > 1: we lead.
The headline is the ratio against the fastest peer.

Set-up (idempotent, skipped with --no-install): as root, apt-get installs libllvm19 when
its library is missing; the repo's .venv is made (python3 -m venv, as tests/validation/
run.sh does) and mitsuba, numpy and bpy are pip-installed into it when they do not
import; then the script re-runs itself with the .venv's python. bpy 5.0 wheels exist
for Python 3.11 only (Debian bookworm's python3): on another Python, cycles is skipped
with the reason printed.

Printed: JSON on stdout; a Markdown table per spp on stderr.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
VENV = os.path.join(ROOT, ".venv")
VENV_PY = os.path.join(VENV, "bin", "python")
MITSUBA_SCRIPT = os.path.join(ROOT, "tests", "validation", "mitsuba_cornell.py")
CYCLES_SCRIPT = os.path.join(HERE, "cycles_cornell.py")

MITSUBA_PIN = "mitsuba==3.9.1"
BPY_PIN = "bpy==5.0.1"
BPY_PYTHON = (3, 11)
ALL_PEERS = ("mitsuba-llvm", "mitsuba-scalar", "cycles")
SCENES = ("cornell-box", "cornell-caustics")
# The image-mean tolerance per scene: ~3 sigma of a 4 M-sample image's mean (docs/VALIDATION.md).
MEAN_TOLERANCE = {"cornell-box": 0.005, "cornell-caustics": 0.01}
CYCLES_SKIPPED = {
    "cornell-caustics": "skipped on cornell-caustics: Cycles has no analytic sphere (its "
                        "spheres are meshes), so it cannot render the same image, and "
                        "bench/cycles_cornell.py builds the box only"}


def log(msg):
    print(f"bench: {msg}", file=sys.stderr, flush=True)


# ---------------------------------------------------------------- pure helpers

def last_json_object(text):
    for line in reversed(text.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                obj = json.loads(line)
            except ValueError:
                continue
            if isinstance(obj, dict):
                return obj
    return None


def interleave(peers, ours="ours"):
    """One round's order: peer A, ours, peer B, ours, ..."""
    order = []
    for p in peers:
        order += [p, ours]
    return order


def summarize(runs):
    """Best run (highest samples/s) and the list of all, from JSON run records."""
    best = max(runs, key=lambda r: r["samples_per_second"])
    return {"samples": best["samples"],
            "seconds": best["seconds"],
            "process_seconds": best.get("process_seconds"),
            "samples_per_second": best["samples_per_second"],
            "samples_per_second_all": [r["samples_per_second"] for r in runs],
            "seconds_all": [r["seconds"] for r in runs],
            "process_seconds_all": [r.get("process_seconds") for r in runs],
            "load_before_all": [r.get("load_before") for r in runs]}


def ratios(ours, peer, paired):
    """Ours-over-peer ratios; `paired` is [(our sps, the peer's sps just before), ...]."""
    out = {"speed_ratio": ours["samples_per_second"] / peer["samples_per_second"],
           "paired_ratios": [o / p for o, p in paired]}
    if ours.get("noise") and peer.get("noise"):
        out["noise_ratio"] = ours["noise"] / peer["noise"]
        out["efficiency_ratio"] = out["speed_ratio"] / out["noise_ratio"] ** 2
    return out


# ---------------------------------------------------------------- set-up

def aliquot_binary(path, who="bench"):
    """`path` as given, else under the repository's root; absolute. Exits unless it runs."""
    if not os.path.isabs(path) and not os.path.exists(path):
        path = os.path.join(ROOT, path)
    found = os.path.abspath(path)
    if not os.access(found, os.X_OK):
        raise SystemExit(f"{who}: aliquot binary not found: {path}")
    return found


def libllvm19_path():
    """Debian's libLLVM 19 shared library, or None (read from the package's file list)."""
    try:
        out = subprocess.run(["dpkg", "-L", "libllvm19"], capture_output=True, text=True,
                             check=False).stdout
    except OSError:
        return None
    for line in out.splitlines():
        if "/libLLVM.so.19" in line and os.path.exists(line.strip()):
            return line.strip()
    return None


def ensure_libllvm19(install):
    lib = libllvm19_path()
    if lib or not install:
        return lib
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        log("libllvm19 missing and not root with apt-get: mitsuba-llvm will be skipped")
        return None
    log("installing Debian's libllvm19 (for Mitsuba's llvm_ad_rgb)")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    if subprocess.run(["apt-get", "install", "-y", "-qq", "libllvm19"], env=env).returncode:
        subprocess.run(["apt-get", "update", "-qq"], env=env)
        subprocess.run(["apt-get", "install", "-y", "-qq", "libllvm19"], env=env)
    return libllvm19_path()


def in_venv():
    return os.path.realpath(sys.prefix) == os.path.realpath(VENV)


def ensure_venv(peers, install, script=__file__):
    """Make .venv and pip-install what the peers need; re-exec `script` (this one by
    default) in it, with the same arguments. Returns notes."""
    if not in_venv():
        if not os.path.exists(VENV_PY):
            if not install:
                raise SystemExit("bench: no .venv (run without --no-install to make it)")
            log("creating .venv")
            subprocess.run([sys.executable, "-m", "venv", VENV], check=True)
        os.execv(VENV_PY, [VENV_PY, os.path.abspath(script)] + sys.argv[1:])
    notes = {}
    want = [("mitsuba", MITSUBA_PIN), ("numpy", "numpy>=1.24")]
    if "cycles" in peers:
        if sys.version_info[:2] != BPY_PYTHON:
            notes["cycles"] = (f"skipped: bpy 5.0 needs Python {BPY_PYTHON[0]}.{BPY_PYTHON[1]}, "
                               f"this is {sys.version.split()[0]}")
        else:
            want.append(("bpy", BPY_PIN))
    missing = []
    for module, pin in want:
        if subprocess.run([sys.executable, "-c", f"import {module}"],
                          capture_output=True).returncode != 0:
            missing.append(pin)
    if missing:
        if not install:
            raise SystemExit(f"bench: .venv lacks {', '.join(missing)}")
        log(f"pip-installing {' '.join(missing)} into .venv")
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet",
                        "--disable-pip-version-check"] + missing, check=True)
    return notes


# ---------------------------------------------------------------- runs

def run_json(cmd, what, env=None):
    load = os.getloadavg()[0]
    log(f"{what} (load {load:.2f}): {' '.join(cmd)}")
    start = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    process_seconds = time.monotonic() - start
    if p.returncode != 0:
        sys.stderr.write(p.stdout[-4000:] + p.stderr[-4000:])
        raise SystemExit(f"bench: {what} failed with exit status {p.returncode}")
    obj = last_json_object(p.stdout)
    if obj is None:
        sys.stderr.write(p.stdout[-4000:] + p.stderr[-4000:])
        raise SystemExit(f"bench: {what} printed no JSON object")
    # Mitsuba's and Cycles' scripts say "samples"; aliquot render --json "samples_done".
    if "samples" not in obj and "samples_done" in obj:
        obj["samples"] = obj["samples_done"]
    for key in ("samples", "seconds", "samples_per_second"):
        if key not in obj:
            raise SystemExit(f"bench: {what}: JSON lacks {key!r}: {obj}")
    obj["load_before"] = round(load, 2)
    # From start to exit, beside the render's own seconds: ours adds loading the scene,
    # writing the EXR and freeing; a peer its interpreter, imports and JIT warm-up.
    obj["process_seconds"] = round(process_seconds, 4)
    log(f"  {obj['samples_per_second'] / 1e6:.3f} M samples/s; render "
        f"{obj['seconds']:.2f} s, process {process_seconds:.2f} s")
    return obj


def seconds_pair(summary):
    """'render / process' seconds of a summarized renderer's best run."""
    process = summary.get("process_seconds")
    return (f"{summary['seconds']:.2f} / " +
            (f"{process:.2f}" if process is not None else "?"))


def markdown(scene, spp, res, results, headline):
    rows = [f"{scene} {res}, {spp} spp:", "",
            "| renderer | samples/s (all runs) | best | render / process s (best) | noise | "
            "mean vs ref | speed ratio | noise ratio | efficiency |",
            "|---|---|---|---|---|---|---|---|---|"]
    for name, r in results["renderers"].items():
        runs = " / ".join(f"{x / 1e6:.2f}" for x in r["samples_per_second_all"])
        cmp = results["ratios"].get(name, {})
        fmt = (lambda k: f"{cmp[k]:.2f}" if k in cmp else "")
        noise_ratio = f"{cmp['noise_ratio']:.3f}" if "noise_ratio" in cmp else ""
        rows.append(f"| {name} | {runs} M | {r['samples_per_second'] / 1e6:.2f} M | "
                    f"{seconds_pair(r)} | {r['noise']:.6f} | {100 * r['mean_rel']:+.3f} % | "
                    f"{fmt('speed_ratio')} | {noise_ratio} | {fmt('efficiency_ratio')} |")
    if headline:
        rows.append(f"\nheadline: {headline}")
    return "\n".join(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description="Aliquot vs its CPU peers: samples/s and noise.")
    ap.add_argument("--aliquot", default=os.path.join("build", "bin", "aliquot"))
    ap.add_argument("--spp", type=int, nargs="+", default=[64])
    ap.add_argument("--scene", choices=SCENES, default="cornell-box")
    ap.add_argument("--resolution", default="256x256")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--peers", default=",".join(ALL_PEERS),
                    help=f"comma-separated, in interleaving order (default {','.join(ALL_PEERS)})")
    ap.add_argument("--reference", default=None, help="high-spp EXR to measure noise against")
    ap.add_argument("--reference-spp", type=int, default=4096,
                    help="spp of the cached Mitsuba reference made when none is given")
    ap.add_argument("--mean-tolerance", type=float, default=None,
                    help="relative image-mean difference above which a peer's image is "
                         "flagged as not the same image (default 0.005 on the box, 0.01 "
                         "on caustics)")
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "build", "validation"))
    ap.add_argument("--repeat", type=int, default=3,
                    help="interleaved rounds; the best run of each renderer counts")
    ap.add_argument("--no-install", action="store_true",
                    help="install nothing (no apt-get, no .venv, no pip)")
    args = ap.parse_args(argv)

    peers = [p.strip() for p in args.peers.split(",") if p.strip()]
    for p in peers:
        if p not in ALL_PEERS:
            ap.error(f"unknown peer {p!r} (have {', '.join(ALL_PEERS)})")
    if args.repeat < 1 or args.threads < 1 or min(args.spp) < 1:
        ap.error("--repeat, --spp and --threads must be positive")

    if args.mean_tolerance is None:
        args.mean_tolerance = MEAN_TOLERANCE[args.scene]
    skipped = {}
    if "cycles" in peers and args.scene in CYCLES_SKIPPED:
        skipped["cycles"] = CYCLES_SKIPPED[args.scene]
        peers = [p for p in peers if p != "cycles"]
    notes = ensure_venv(peers, not args.no_install)  # re-runs this script in .venv
    for name, why in skipped.items():
        log(f"{name}: {why}")
    notes.update(skipped)
    env = dict(os.environ)
    if "mitsuba-llvm" in peers:
        lib = ensure_libllvm19(not args.no_install)
        if lib:
            env["DRJIT_LIBLLVM_PATH"] = lib
        else:
            notes["mitsuba-llvm"] = "skipped: no libLLVM 19 (Debian package libllvm19)"
    peers = [p for p in peers if p not in notes]
    if not peers:
        raise SystemExit(f"bench: no peer can run: {notes}")

    sys.path.insert(0, os.path.join(ROOT, "tests", "validation"))
    from compare_to_mitsuba import InputError, mean_abs_diff, read_exr_rgb

    os.makedirs(args.out_dir, exist_ok=True)
    py = sys.executable
    res = args.resolution
    aliquot = aliquot_binary(args.aliquot)

    # Reference first, so that making it cannot disturb the timings.
    ref_path = args.reference
    if ref_path is None:
        ref_path = os.path.join(
            args.out_dir, f"mitsuba-{args.scene}-{res}-ref-{args.reference_spp}spp-seed5000.exr")
        if not os.path.exists(ref_path):
            variant = "llvm_rgb" if "DRJIT_LIBLLVM_PATH" in env else "scalar_rgb"
            run_json([py, MITSUBA_SCRIPT, "--scene", args.scene, "--variant", variant,
                      "--resolution", res,
                      "--spp", str(args.reference_spp), "--seed", "5000",
                      "--threads", str(args.threads), "--out", ref_path],
                     f"reference at {args.reference_spp} spp (cached for next time)", env)
    try:
        ref = read_exr_rgb(ref_path)
    except InputError as e:
        raise SystemExit(f"bench: {e}")
    ref_mean = float(ref.mean())

    load_start = os.getloadavg()
    all_results = []
    for spp in args.spp:
        def out(name):
            return os.path.join(args.out_dir, f"bench-{args.scene}-{name}-{res}-{spp}spp.exr")
        common = ["--resolution", res, "--spp", str(spp), "--seed", str(args.seed),
                  "--threads", str(args.threads)]
        cmds = {
            "mitsuba-llvm": [py, MITSUBA_SCRIPT, "--scene", args.scene, "--variant", "llvm_rgb",
                             "--warmup-spp", "1", *common, "--out", out("mitsuba-llvm")],
            "mitsuba-scalar": [py, MITSUBA_SCRIPT, "--scene", args.scene,
                               "--variant", "scalar_rgb", *common,
                               "--out", out("mitsuba-scalar")],
            "cycles": [py, CYCLES_SCRIPT, *common, "--out", out("cycles")],
            "ours": [aliquot, "render", "--scene", args.scene, *common,
                     "--json", "--out", out("ours")],
        }
        runs = {name: [] for name in peers + ["ours"]}
        paired = {p: [] for p in peers}
        load_before = os.getloadavg()
        for rep in range(args.repeat):
            order = interleave(peers)
            for i, name in enumerate(order):
                r = run_json(cmds[name], f"{spp} spp: {name} ({rep + 1}/{args.repeat})", env)
                runs[name].append(r)
                if name == "ours":
                    peer = order[i - 1]
                    paired[peer].append((r["samples_per_second"],
                                         runs[peer][-1]["samples_per_second"]))
        load_after = os.getloadavg()

        results = {"spp": spp, "renderers": {}, "ratios": {},
                   "load_before": [round(x, 2) for x in load_before],
                   "load_after": [round(x, 2) for x in load_after]}
        warnings = []
        for name in peers + ["ours"]:
            s = summarize(runs[name])
            img = read_exr_rgb(runs[name][0].get("output") or out(name))
            s["noise"] = mean_abs_diff(img, ref)
            s["mean_rel"] = float(img.mean()) / ref_mean - 1.0
            first = runs[name][0]
            for key in ("variant", "mitsuba_version", "blender_version", "warmup_seconds",
                        "settings"):
                if first.get(key) is not None:
                    s[key] = first[key]
            if s["samples"] != runs["ours"][0]["samples"]:
                warnings.append(f"{name}: sample count differs from ours")
            if abs(s["mean_rel"]) > args.mean_tolerance:
                warnings.append(f"{name}: image mean {100 * s['mean_rel']:+.2f} % off the "
                                "reference: not the same image, its noise ratio is not "
                                "a comparison")
            results["renderers"][name] = s
        for p in peers:
            results["ratios"][p] = ratios(results["renderers"]["ours"],
                                          results["renderers"][p], paired[p])
        fastest = max(peers, key=lambda p: results["renderers"][p]["samples_per_second"])
        h = results["ratios"][fastest]
        results["fastest_peer"] = fastest
        headline = (f"ours / {fastest} (fastest peer): speed {h['speed_ratio']:.2f}x, "
                    f"noise ratio {h.get('noise_ratio', float('nan')):.3f}, "
                    f"efficiency {h.get('efficiency_ratio', float('nan')):.2f}x")
        results["headline"] = headline
        if warnings:
            results["warnings"] = warnings
        all_results.append(results)
        print(markdown(args.scene, spp, res, results, headline), file=sys.stderr, flush=True)

    print(json.dumps({"scene": args.scene, "results": all_results, "notes": notes,
                      "resolution": res,
                      "threads": args.threads, "repeat": args.repeat, "peers": peers,
                      "reference": ref_path, "reference_mean": ref_mean,
                      "load_start": [round(x, 2) for x in load_start],
                      "load_end": [round(x, 2) for x in os.getloadavg()],
                      "measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
