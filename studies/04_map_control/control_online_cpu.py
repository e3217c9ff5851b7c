"""Lesson 04 side experiment (issue 16): why does a rerun of the recorded online run diverge from the recording?

studies/04_map_control/control_online_seeds.py found a fresh-process rerun of the scripted online run (seed 0) agreeing with the
recording (results/control.json) to 1e-4 m/s for 11 s walking and 8.7 s running, then drifting apart.  The recording was made
on a host whose torch kernels ran at cpu capability AVX512 (the manifest's ``trained_on`` of the GMM-RNN); this
machine runs AVX2.  This tool runs the same scripted run in fresh processes: twice at this host's capability, once
with torch's portable kernels (``ATEN_CPU_CAPABILITY=default``), and compares them batch by batch.

    OMP_NUM_THREADS=1 python studies/04_map_control/control_online_cpu.py --out studies/04_map_control/control_online_cpu_results.json  # ~3 min

Writes nothing to checkpoints/.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

from control_online_seeds import divergence  # the script's own folder is on sys.path

from course_lib.paths import CHECKPOINTS
from course_lib.results import provenance

COMMAND = "OMP_NUM_THREADS=1 python studies/04_map_control/control_online_cpu.py --out studies/04_map_control/control_online_cpu_results.json"
GAITS = ("walk", "run")


def child(path: str) -> None:
    """One scripted run per gait (seed 0) -> JSON at path: the capability, held share and every batch."""
    import torch

    from course_lib.experiments import control as C

    torch.set_num_threads(1)
    out = {"cpu_capability": torch.backends.cpu.get_cpu_capability()}
    for gait in GAITS:
        r = C.online_run(gait, 0)
        out[gait] = {"held": r["speed_held"], "batches": r["batches"]}
    with open(path, "w") as f:
        json.dump(out, f)


def run(capability: str | None) -> dict:
    """A fresh interpreter for one run; capability None keeps the host's."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    if capability:
        env["ATEN_CPU_CAPABILITY"] = capability
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "run.json")
        subprocess.run([sys.executable, __file__, "--child", path], env=env, check=True)
        with open(path) as f:
            return json.load(f)


def compare(a: dict, b: dict, tol: float = 1e-4) -> dict:
    """Batch-by-batch comparison of one gait's two runs (control_online_seeds.divergence): the first batch that
    differs at all, the first that differs by more than tol m/s, batch 0's speed difference, both held shares."""
    exact, beyond = divergence(a, b, 0.0), divergence(a, b, tol)
    return {"first_batch_different": exact["first_batch"], "first_batch_beyond_tol": beyond["first_batch"],
            "t_beyond_tol": beyond.get("t"),
            "batch0_speed_difference": abs(a["batches"][0]["speed"] - b["batches"][0]["speed"]),
            "held": [a["held"], b["held"]]}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return child(args.child)
    if not args.out:
        parser.error("--out is required")
    host, again, portable = run(None), run(None), run("default")
    out = {"command": COMMAND, "capabilities": [host["cpu_capability"], again["cpu_capability"],
                                                 portable["cpu_capability"]],
           "same_capability": {g: compare(host[g], again[g]) for g in GAITS},
           "portable_kernels": {g: compare(host[g], portable[g]) for g in GAITS}}
    # the runs were child processes: the files the prior loads there (design.default_prior)
    out = {**out, **provenance(checkpoints=[CHECKPOINTS / "gmm_rnn.pt", CHECKPOINTS / "gmm_rnn_stats.npz"])}
    with open(args.out, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
