"""Timings of the course's core operations, as a Markdown table.

    python -m course_lib.timings                 # every benchmark, median of 20 runs
    python -m course_lib.timings --only fk --repeat 50

A benchmark is a setup function, registered with ``@register("name")``, that builds
its inputs and returns a zero-argument callable; only that callable is timed (after
``WARMUP`` untimed calls, which also trigger JAX compilation).  To add a row, add
such a function here.  Importing this module runs nothing.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

WARMUP = 3  # untimed calls before timing (JIT compilation, allocator warm-up)
FK_SHAPE = (64, 240)  # batch x frames of the forward-kinematics benchmarks (x 21 joints)

BENCHMARKS: list[tuple[str, Callable[[], Callable[[], object]]]] = []


def register(name: str):
    """Decorator: add ``setup() -> timed_callable`` to BENCHMARKS under ``name``."""
    def add(setup: Callable[[], Callable[[], object]]):
        BENCHMARKS.append((name, setup))
        return setup
    return add


def time_ms(fn: Callable[[], object], repeat: int, warmup: int = WARMUP) -> list[float]:
    """Wall-clock milliseconds of `repeat` calls of fn, after `warmup` untimed calls."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(1000.0 * (time.perf_counter() - start))
    return times


def _fk_inputs(seed: int = 0):
    """Random float32 numpy inputs for FK on the canonical skeleton: rotations (N, T, J, 4), root (N, T, 3)."""
    import numpy as np

    from course_lib.skeleton import Skeleton

    sk = Skeleton.canonical()
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(*FK_SHAPE, sk.num_joints, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return sk, q, rng.normal(size=(*FK_SHAPE, 3)).astype(np.float32), sk.offsets.astype(np.float32)


@register("fk torch float32 64x240x21")
def _fk_torch():
    import torch

    from course_lib.skeleton import forward_kinematics

    sk, q, root, off = _fk_inputs()
    q, root, off = torch.from_numpy(q), torch.from_numpy(root), torch.from_numpy(off)
    return lambda: forward_kinematics(q, root, off, sk.parents)


@register("fk jax jit float32 64x240x21")
def _fk_jax():
    import jax.numpy as jnp

    from course_lib.jax_reference import forward_kinematics

    sk, q, root, off = _fk_inputs()
    q, root, off = jnp.asarray(q), jnp.asarray(root), jnp.asarray(off)
    return lambda: forward_kinematics(q, root, off, sk.parents)[0].block_until_ready()


@register("read_bvh cmu_07_01_walk")
def _read_bvh():
    from course_lib.bvh import CMU_SCALE, cmu_sample_path, read_bvh

    path = cmu_sample_path()  # package data: always there
    return lambda: read_bvh(path, CMU_SCALE)


@register("action classifier features 64x60x90 (FID/IS)")
def _classifier_features():
    # held-out accuracies: python -m course_lib.evaluation.classifiers --eval
    import torch

    from course_lib.evaluation.classifiers import checkpoint_path, load_classifier

    if not checkpoint_path("action").exists():
        return None
    clf, x = load_classifier("action"), torch.randn(64, 60, 90)
    return lambda: clf.features(x).detach()


@register("synthetic locomotion clip 4 s @ 120 fps")
def _generate_locomotion():
    # default datasets: 1800 such clips + 320 action clips; ms per clip x 2120 / cores ~ make data's time
    from course_lib.synthetic import generate_locomotion, make_subject

    subject, seeds = make_subject(0, seed=0), iter(range(10**6))
    return lambda: generate_locomotion(subject, None, duration=4.0, fps=120, seed=next(seeds))


@register("synthetic action clip (jump, lift) @ 120 fps")
def _generate_actions():
    from course_lib.synthetic import generate_action, make_subject

    subject, seeds = make_subject(1, seed=0), iter(range(10**6))
    return lambda: [generate_action(subject, a, seed=next(seeds)) for a in ("jump", "lift")][-1]


MOGLOW_BATCH = (64, 100)  # sequences x generated frames of the batched MoGlow benchmark


def _moglow_model():
    """The shipped lesson-06 model, else an untrained one of the same size (same cost): (model, tau, D)."""
    import torch

    from course_lib.experiments.moglow import CHECKPOINTS, TAU, load_model
    from course_lib.models.moglow import MoGlow, MoGlowConfig

    torch.manual_seed(0)
    path = CHECKPOINTS / "moglow.pt"
    model = load_model("moglow") if path.exists() else MoGlow(MoGlowConfig.cpu(61, 3, TAU)).eval()
    return model, model.config.tau, model.config.pose_dim


@register("moglow sample batched 64 x 100 frames (frames/s = 6400000 / ms)")
def _moglow_batched():
    import torch

    model, tau, D = _moglow_model()
    N, T = MOGLOW_BATCH
    x0, c = torch.zeros(N, tau, D), torch.zeros(N, tau + T, 3)
    return lambda: model.sample(c, x0, temperature=1.0)


@register("moglow stream one frame, batch 1 (frames/s = 1000 / ms)")
def _moglow_stream():
    import torch

    model, tau, D = _moglow_model()
    stream, c = model.stream(torch.zeros(1, tau, D), torch.zeros(1, tau, 3)), torch.zeros(1, 3)
    return lambda: stream.step(c)


ONLINE_BATCH = 10  # frames per OnlineController.step (its latency)


@register("online control step, 10 frames, 1 thread (frames/s = 10000 / ms)")
def _online_control():
    # lesson 04 (course_lib.control.online, Wang et al. sec. 5.3): the paper's 30 fps on a GTX 970; the issue asks 60
    import math

    import torch

    from course_lib.control import OnlineConfig, OnlineController
    from course_lib.experiments.gmm_rnn import CHECKPOINTS
    from course_lib.synthetic import ControlProgram, generate_locomotion, make_subject

    if not (CHECKPOINTS / "gmm_rnn.pt").exists():
        return None
    start = generate_locomotion(make_subject(0, seed=0), ControlProgram.constant("walk", 1.2, 2.0), duration=2.0,
                                seed=0).resample(30.0)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    ctrl = OnlineController(start=start, config=OnlineConfig(batch=ONLINE_BATCH))
    torch.set_num_threads(threads)
    turns = iter(range(10**6))

    def step():
        torch.set_num_threads(1)
        try:  # a turn every 2 steps, speed 1.2 m/s: the work of a steered run
            return ctrl.step(1.2, math.pi * (next(turns) // 6 % 2))
        finally:
            torch.set_num_threads(threads)
    return step


def run(only: str | None = None, repeat: int = 20) -> str:
    """-> Markdown table of the selected benchmarks (name contains `only`): median and min ms."""
    import torch

    names = [name for name, _ in BENCHMARKS if not only or only in name]
    if not names:
        raise ValueError(f"no benchmark name contains {only!r}; benchmarks: {', '.join(n for n, _ in BENCHMARKS)}")
    rows = [f"torch {torch.__version__}, {torch.get_num_threads()} threads, {os.cpu_count()} CPUs; "
            f"median of {repeat} runs after {WARMUP} warm-up calls", "",
            "| benchmark | median ms | min ms |", "|---|---:|---:|"]
    for name, setup in BENCHMARKS:
        if name not in names:
            continue
        fn = setup()
        if fn is None:
            rows.append(f"| {name} | n/a (module or data missing) | |")
            continue
        t = time_ms(fn, repeat)
        rows.append(f"| {name} | {statistics.median(t):.2f} | {min(t):.2f} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="run the benchmarks whose name contains this text")
    parser.add_argument("--repeat", type=int, default=20, help="timed runs per benchmark (default 20)")
    parser.add_argument("--threads", type=int, help="torch intra-op threads (default: torch's own choice); "
                        "small batched ops such as FK are often fastest with 1")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    if args.threads is not None:
        import torch

        torch.set_num_threads(max(1, args.threads))
    accuracy = not args.only or args.only in "classifier accuracy"  # `--only accuracy` prints it alone
    try:
        print(run(args.only, args.repeat))
    except ValueError as err:
        if not accuracy:
            parser.error(str(err))
    if accuracy:
        print(accuracy_report())


def accuracy_report() -> str:
    """Held-out accuracy of the shipped action/style classifiers (Markdown), or why it is missing."""
    from course_lib.evaluation.classifiers import checkpoint_path, evaluate_shipped

    if not all(checkpoint_path(t).exists() for t in ("action", "style")):
        return "\nclassifier accuracy: n/a (checkpoints missing)"
    rows = ["", "| classifier (held-out subjects) | accuracy |", "|---|---:|"]
    rows += [f"| {task} | {acc:.3f} |" for task, acc in evaluate_shipped().items()]
    return "\n".join(rows)


if __name__ == "__main__":
    main()
