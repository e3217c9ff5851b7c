"""Reference answers and self-checks for the exercises of notebooks/02_vae_lstm.ipynb.

Students write their own version in the notebook; each ``check_*`` recomputes the answer another way on the
inputs it is given (or builds its own) and raises an AssertionError that says what is wrong.
"""

from __future__ import annotations

import math

import numpy as np
import torch

__all__ = ["check_canvas", "check_own_root_error", "check_prior_region", "check_sampler_memory",
           "prior_region_probability"]


def check_canvas(n_steps: int, canvas_shape, model) -> None:
    """Exercise 1: the number of pooled steps and the motion canvas's shape for a 480-frame clip."""
    with torch.no_grad():
        mu, _ = model.encode(torch.zeros(1, 480, model.config.dim))
        canvas = model.run_decoder(model.encode_control(torch.zeros(1, 480, model.config.control_dim)), mu)
    assert n_steps == mu.shape[1], f"{mu.shape[1]} latent steps, not {n_steps}: count the two max-pools of 2"
    assert tuple(canvas_shape) == tuple(canvas.shape[1:]), \
        f"the canvas is (LSTM units, steps) = {tuple(canvas.shape[1:])}, not {tuple(canvas_shape)}"


def prior_region_probability(latent_dim: int, floor: float = -1.0) -> float:
    """P(every coordinate of z ~ N(0, I_U) is above ``floor``) = Phi(-floor)^U (the coordinates are independent)."""
    return (0.5 * (1 + math.erf(-floor / math.sqrt(2)))) ** latent_dim


def check_prior_region(p_inside: float, latent_dim: int) -> None:
    """Exercise 2: the chance that a prior draw lands where an ELU-capped posterior mean (every mu > -1) can be."""
    want = prior_region_probability(latent_dim)
    one = prior_region_probability(1)
    p = float(p_inside)
    assert 0.0 <= p <= 1.0, f"a probability lies in [0, 1], got {p}"
    assert not math.isclose(p, one, rel_tol=1e-3) or latent_dim == 1, \
        f"{p:.4f} is one coordinate's chance Phi(1); all {latent_dim} independent coordinates must be above -1"
    assert abs(p - (1 - one) ** latent_dim) > 1e-12, "that is the chance that every coordinate is *below* -1"
    # a Monte-Carlo estimate in few dimensions confirms the product rule the answer relies on
    z = torch.randn(200_000, 4, generator=torch.Generator().manual_seed(0))
    assert abs(float((z > -1).all(1).double().mean()) - prior_region_probability(4)) < 0.005
    assert math.isclose(p, want, rel_tol=1e-3), \
        f"got {p:.4g}, want {want:.4g}: P(z_k > -1) = Phi(1) = {one:.4f} per coordinate, multiplied over {latent_dim}"


def _late_distance(model, control, ds, starts, seed_a, seed_b, per_step, frames):
    from course_lib.experiments import vae_lstm as R

    a, b = (model.generate(control, generator=torch.Generator().manual_seed(s), per_step=per_step)
            for s in (seed_a, seed_b))
    return R.joint_distance(a[:, -frames:], b[:, -frames:], ds, starts, control[:, -frames:])


def check_sampler_memory(late: dict, model, control, ds, starts, frames: int = 40) -> None:
    """Exercise 3: the mean joint distance (m) over the last ``frames`` frames between two prior draws (seeds 3
    and 4) under one control, root on the given control's path, for Algorithm 1 and for z_t every step."""
    assert set(late) == {"algorithm1", "per_step"}, f"fill late['algorithm1'] and late['per_step'], got {set(late)}"
    for key in late:
        want = _late_distance(model, control, ds, starts, 3, 4, key == "per_step", frames)
        got = float(late[key])
        if got == 0.0 and want > 1e-6:
            raise AssertionError(f"late[{key!r}] is still 0: generate two samples (seeds 3 and 4) and measure them")
        assert math.isclose(got, want, rel_tol=1e-4, abs_tol=1e-7), \
            f"late[{key!r}] = {got:.5g} m, want {want:.5g} m: the mean over the last {frames} frames and all 21 " \
            f"joints of ||a - b||, both samples placed on the given control's root path (`R.with_control`)"


def check_own_root_error(err_own: float, err_given: float, model, x, ds, starts, frame: int = 210) -> None:
    """Exercise 4: Table 1's error (mean squared joint distance, m^2) at ``frame`` of the 4-frame output on clips
    ``x``, with the root from the model's own control channels and from the given control."""
    from course_lib.experiments import vae_lstm as R

    pred = model.predict(x[:, :4], x[..., -3:])
    gt = R.to_world(x, ds, starts)
    ref = {}
    for key, feats in (("own", pred), ("given", R.with_control(pred, x[..., -3:]))):
        ref[key] = float(((R.to_world(feats, ds, starts)[:, frame] - gt[:, frame]) ** 2).sum(-1).mean())
    got = {"own": float(err_own), "given": float(err_given)}
    if got["own"] == got["given"] == 0.0:
        raise AssertionError("both errors are still 0: decode the 4-frame output twice and compare with the truth")
    if math.isclose(got["own"], ref["given"], rel_tol=1e-4) and not math.isclose(ref["own"], ref["given"]):
        raise AssertionError("err_own is the error with the given control's root: keep the model's own control "
                             "channels (do not call R.with_control) for err_own")
    for key in got:
        if math.isclose(got[key], np.sqrt(ref[key]), rel_tol=1e-3):
            raise AssertionError(f"err_{key} looks like a distance, not its square: Table 1 averages squared "
                                 "joint distances (m^2)")
        assert math.isclose(got[key], ref[key], rel_tol=1e-4), \
            f"err_{key} = {got[key]:.5g}, want {ref[key]:.5g} m^2: the squared distance between the output's and " \
            f"the truth's world joints at frame {frame}, summed over x, y, z, averaged over joints and clips"
