"""One training loop for every model in the course, and reproducible checkpoints.

Taught in notebooks/01_vae_basics.ipynb and used by every later lesson.

The trainer knows nothing about any model (minGPT's trainer): it only calls
``model.loss(batch) -> dict`` whose ``"loss"`` entry is minimised; every other
entry (scalars or small vectors such as a KL per latent dimension) is logged in
a :class:`History` (history.py).  Checkpoints are ``state_dict`` + JSON config + course_lib
version, hashed with sha256 and listed in ``checkpoints/MANIFEST.json`` (provenance only) together
with the one command that reproduces them, and in a sidecar ``<file>.sha256`` beside the
file (see `course_lib.checksums`); what a training measured (its metrics) goes to its lesson's
``results/<name>.json`` (`course_lib.results`); they are always loaded with
``torch.load(..., weights_only=True)``, and only after their sha256 matched the manifest's
entry or, for a file the manifest does not list (a copy elsewhere), its sidecar.
"""

from __future__ import annotations

import dataclasses
import json
import os
import platform
import random
import time
import typing
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from . import __version__
from .checksums import sha256_file, write_sidecar
from .history import History
from .manifest import entry_name, manifest_path, read_manifest, update_manifest, verify_file
from .paths import missing_checkpoints_hint
from .results import checkpoint_metrics, record_checkpoint_metrics

__all__ = [
    "History",
    "fit",
    "load_checkpoint",
    "make_optimizer",
    "save_checkpoint",
    "seed_everything",
    "sha256_file",
]


# ----------------------------------------------------------------------------- seeding


def seed_everything(seed: int) -> torch.Generator:
    """Seed Python, NumPy and torch's global generators; return a fresh torch.Generator seeded alike."""
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise TypeError(f"seed must be an int, got {type(seed).__name__}")
    random.seed(int(seed))
    np.random.seed(int(seed) % 2**32)
    torch.manual_seed(int(seed))
    return torch.Generator().manual_seed(int(seed))


# ----------------------------------------------------------------------------- fit


def make_optimizer(params, optimizer: str | Callable = "adam", lr: float = 1e-3,
                   weight_decay: float = 0.0) -> torch.optim.Optimizer:
    """'adam' | 'rmsprop' | 'sgd' | callable(params, lr) -> torch.optim.Optimizer."""
    if callable(optimizer):
        return optimizer(params, lr)
    table = {"adam": torch.optim.Adam, "rmsprop": torch.optim.RMSprop, "sgd": torch.optim.SGD}
    if optimizer not in table:
        raise ValueError(f"optimizer must be one of {sorted(table)} or a callable, got {optimizer!r}")
    return table[optimizer](params, lr=lr, weight_decay=weight_decay)


def _batches(data, steps_per_epoch: int | None):
    """Yield epochs, each an iterator of batches, from a DataLoader/iterable or a batch-making callable."""
    if callable(data) and not hasattr(data, "__iter__"):
        if steps_per_epoch is None:
            raise ValueError("data is a callable and epochs= was given: pass steps_per_epoch (calls per epoch)")
        while True:
            yield (data() for _ in range(steps_per_epoch))
    elif hasattr(data, "__iter__"):
        if iter(data) is data:  # a one-shot iterator/generator: one single (possibly endless) epoch
            yield data
            return
        while True:
            yield iter(data)
    else:
        raise TypeError(f"data must be a DataLoader, an iterable of batches or a callable, got {type(data).__name__}")


def _to_logs(out: dict, step: int) -> dict[str, float | np.ndarray]:
    """Detach a loss dict into floats / numpy arrays; raise on a missing or non-finite 'loss'."""
    if not isinstance(out, dict) or "loss" not in out:
        raise KeyError(f"model.loss(batch) must return a dict with key 'loss', got {type(out).__name__}"
                       + (f" with keys {sorted(out)}" if isinstance(out, dict) else ""))
    if out["loss"].ndim != 0:
        raise ValueError(f"out['loss'] must be a scalar tensor, got shape {tuple(out['loss'].shape)}")
    if not torch.isfinite(out["loss"]):
        raise FloatingPointError(f"non-finite loss {out['loss'].item()} at step {step}")
    logs = {}
    for key, value in out.items():
        if torch.is_tensor(value):
            value = value.detach().double().cpu()
            logs[key] = value.item() if value.ndim == 0 else value.numpy()
        elif isinstance(value, (int, float, np.floating)):
            logs[key] = float(value)
    return logs


@dataclasses.dataclass
class StepInfo:
    """What a ``fit`` callback sees after each optimiser step; return True from the callback to stop."""

    step: int
    epoch: int
    logs: dict
    model: torch.nn.Module
    optimizer: torch.optim.Optimizer
    history: History


def fit(model: torch.nn.Module, data, *, steps: int | None = None, epochs: int | None = None,
        lr: float = 1e-3, optimizer: str | Callable = "adam", weight_decay: float = 0.0,
        grad_clip: float | None = None, lr_schedule: Callable[[int], float] | None = None,
        steps_per_epoch: int | None = None, callback: Callable[[StepInfo], bool | None] | None = None,
        progress: bool = True, seed: int | None = None, desc: str = "fit",
        optimizer_state: dict | None = None) -> History:
    """Minimise ``model.loss(batch)["loss"]`` over ``data``; return the :class:`History`.

    data: a DataLoader / re-iterable of batches (one pass = one epoch), a one-shot iterator,
    or a callable returning a batch (``steps_per_epoch`` calls = one epoch).  Stops after
    ``steps`` optimiser steps or ``epochs`` epochs, whichever comes first (give at least one).
    lr_schedule: epoch -> factor multiplying ``lr`` (epochs counted from 0).
    grad_clip: max global L2 norm of the gradients (the pre-clip norm is logged as 'grad_norm').
    optimizer_state: an ``optimizer.state_dict()`` to continue from (a run resumed or forked from the
    state a callback kept: with the model's weights, the data's position and torch's RNG state restored,
    it continues exactly).
    """
    if steps is None and epochs is None:
        raise ValueError("fit needs steps= or epochs= (or both; it stops at whichever comes first)")
    if callable(data) and not hasattr(data, "__iter__") and steps_per_epoch is None and epochs is None:
        steps_per_epoch = steps  # a batch-making callable with steps only: the whole run is one epoch
    if seed is not None:
        seed_everything(seed)
    params = [p for p in model.parameters() if p.requires_grad]
    if not params:
        raise ValueError("model has no trainable parameters")
    opt = make_optimizer(params, optimizer, lr, weight_decay)
    if optimizer_state is not None:
        opt.load_state_dict(optimizer_state)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lr_schedule) if lr_schedule is not None else None
    history, step, was_training, t0 = History(), 0, model.training, time.perf_counter()
    total = steps if steps is not None else (epochs * steps_per_epoch if steps_per_epoch else None)
    bar, stop = _progress(total, progress, desc), False
    model.train()
    try:
        for epoch, batches in enumerate(_batches(data, steps_per_epoch)):
            if epochs is not None and epoch >= epochs:
                break
            for batch in batches:
                logs = _train_step(model, opt, batch, grad_clip, step)
                step += 1
                logs["lr"] = opt.param_groups[0]["lr"]
                history.log_step(logs)
                bar.update(1)
                bar.set_postfix(loss=f"{logs['loss']:.4g}", refresh=False)
                stop = callback(StepInfo(step, epoch, logs, model, opt, history)) if callback else False
                if stop or (steps is not None and step >= steps):
                    break
            history.end_epoch()
            if stop or (steps is not None and step >= steps):
                break
            if sched is not None:
                sched.step()
    finally:
        bar.close()
        model.train(was_training)
    history.lr = list(history.step.get("lr", []))
    history.seconds = time.perf_counter() - t0
    return history


def _train_step(model, opt, batch, grad_clip, step) -> dict:
    """One optimiser step on one batch; returns the detached logs."""
    opt.zero_grad(set_to_none=True)
    out = model.loss(batch)
    logs = _to_logs(out, step)
    out["loss"].backward()
    params = [p for group in opt.param_groups for p in group["params"] if p.grad is not None]
    # the global norm before clipping, logged so students can see exploding gradients
    norm = torch.nn.utils.clip_grad_norm_(params, grad_clip if grad_clip is not None else float("inf"))
    logs["grad_norm"] = float(norm)
    opt.step()
    return logs


def _progress(total, progress, desc):
    from tqdm.auto import tqdm

    disabled = not progress or os.environ.get("TQDM_DISABLE", "").strip().lower() not in ("", "0", "false")
    return tqdm(total=total, disable=disabled, desc=desc, leave=False)


# ----------------------------------------------------------------------------- checkpoints


def _jsonable(x):
    """Turn tuples, numpy and torch scalars into plain JSON types."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.generic, torch.Tensor)):
        return x.item()
    return x


def training_environment() -> dict:
    """Where a checkpoint was trained: the versions and the CPU's vector kernels that decide float rounding (a
    long training amplifies rounding into another model, so the same command can give other weights elsewhere)."""
    return {"python": platform.python_version(), "torch": torch.__version__, "numpy": np.__version__,
            "machine": platform.machine(), "cpu_capability": torch.backends.cpu.get_cpu_capability()}


def save_checkpoint(model: torch.nn.Module, config, path: str | os.PathLike, *, command: str,
                    metrics: dict | None = None, overwrite: bool = False,
                    manifest: str | os.PathLike | None = None, environment: dict | None = None) -> dict:
    """Write ``{state_dict, config JSON, course_lib version}`` to ``path`` and record it in the manifest.

    config: the model's config dataclass.  command: the one shell command that reproduces this file.
    manifest: defaults to ``MANIFEST.json`` next to ``path``.  environment: the entry's "trained_on"; None (a
    fresh training) records `training_environment()`, a re-save passes the entry's own ({} when unknown: no field).
    metrics: what the training measured, stored as the checkpoint's entry of its results file
    (`course_lib.results.results_file`: ``results/<NAME>.json`` for the command ``python -m course_lib.reproduce
    NAME``, else ``results/<checkpoint name>.json``; None drops an entry recorded before).
    Returns the manifest entry (provenance only; `recorded_metrics` reads the metrics back).
    """
    path = Path(path)
    if not dataclasses.is_dataclass(config) or isinstance(config, type):
        raise TypeError(f"config must be a dataclass instance, got {type(config).__name__}")
    if not command or not isinstance(command, str):
        raise ValueError("command must be the shell command that reproduces this checkpoint")
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass overwrite=True to replace it")
    config_dict = _jsonable(dataclasses.asdict(config))
    payload = {
        "state_dict": {k: v.detach().cpu().clone() for k, v in model.state_dict().items()},
        "config_json": json.dumps(config_dict, sort_keys=True),
        "config_class": type(config).__name__,
        "model_class": type(model).__name__,
        "course_lib_version": __version__,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(payload, path)
    write_sidecar(path)
    mpath = manifest_path(path, manifest)
    entry = {
        "file": os.path.relpath(path.resolve(), mpath.resolve().parent).replace(os.sep, "/"),
        "sha256": sha256_file(path), "bytes": path.stat().st_size, "config": config_dict,
        "model_class": type(model).__name__, "command": command, "course_lib_version": __version__,
    }
    trained_on = training_environment() if environment is None else environment
    if trained_on:
        entry["trained_on"] = _jsonable(trained_on)
    update_manifest(mpath, entry_name(path, mpath), entry)
    record_checkpoint_metrics(path, None if metrics is None else _jsonable(metrics), manifest=mpath)
    return entry


def record_metrics(path: str | os.PathLike, model_cls, config_cls, **metrics) -> dict:
    """Merge ``metrics`` into a shipped checkpoint's recorded metrics (its entry of its results file), the file,
    its weights, config, command and manifest entry unchanged: where a reproduction stores its evaluation for
    the notebooks.  The checkpoint is loaded first (its sha256 verified, as a ``model_cls``).  Returns its
    manifest entry."""
    path = Path(path)
    load_checkpoint(path, model_cls, config_cls)
    mpath = manifest_path(path, None)
    record_checkpoint_metrics(path, _jsonable(metrics), manifest=mpath, merge=True)
    return read_manifest(mpath)[entry_name(path, mpath)]


def recorded_metrics(path: str | os.PathLike) -> dict:
    """What `save_checkpoint` / `record_metrics` stored about a checkpoint: its entry of its results file ({} when
    none); KeyError when the manifest beside it does not list it."""
    return checkpoint_metrics(path)


def _config_from_dict(config_cls, values: dict):
    """Rebuild a config dataclass from JSON, turning lists back into tuples where the field is a tuple."""
    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    unknown = set(values) - set(fields)
    if unknown:
        raise ValueError(f"checkpoint config has fields {sorted(unknown)} unknown to {config_cls.__name__}")
    hints = typing.get_type_hints(config_cls)
    kwargs = {}
    for name, value in values.items():
        hint = str(hints.get(name, ""))
        is_tuple = "tuple" in hint.lower() or isinstance(fields[name].default, tuple)
        kwargs[name] = tuple(value) if is_tuple and isinstance(value, list) else value
    return config_cls(**kwargs)


def load_checkpoint(path: str | os.PathLike, model_cls, config_cls, *, manifest: str | os.PathLike | None = None,
                    verify: bool = True) -> torch.nn.Module:
    """Rebuild ``model_cls(config_cls(**config))`` from ``path`` and load its weights (eval mode).

    Before loading (``torch.load(weights_only=True)``) the file's sha256 must match the manifest's
    entry (default manifest: MANIFEST.json next to the file) or, where the manifest does not list
    it, its sidecar ``<path>.sha256``; a mismatch, a file known to neither, or an entry without a
    sha256 raise ValueError saying how to proceed.  ``verify=False`` skips the check.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"checkpoint {missing_checkpoints_hint(path)}")
    if verify:
        verify_file(path, manifest)
    payload = torch.load(path, map_location="cpu", weights_only=True)
    if payload.get("config_class") not in (None, config_cls.__name__):
        raise TypeError(f"{path} holds a {payload['config_class']}, not a {config_cls.__name__}")
    config = _config_from_dict(config_cls, json.loads(payload["config_json"]))
    model = model_cls(config)
    model.load_state_dict(payload["state_dict"], strict=True)
    return model.eval()
