"""Reference answers and self-checks for the exercises of notebooks/03_gmm_rnn_refiner.ipynb.

Students write their own version in the notebook; each ``check_*`` builds small inputs itself, runs the student's
function and the library (course_lib.models.gmm_rnn, course_lib.models.refiner) on them, and raises an
AssertionError that says what is wrong.  The two written-out algorithms (the sampling step, one refiner round)
return the largest difference from the library, for the notebook to print.
"""

from __future__ import annotations

import copy
import math

import torch
from torch.nn import functional as F

from course_lib.models.contact_cleanup import leg_columns
from course_lib.models.gmm_rnn import GmmRnn, GmmRnnConfig, mixture_log_prob
from course_lib.models.refiner import (
    Discriminator,
    HistoryBuffer,
    Refiner,
    RefinerConfig,
    _discriminator_step,
    _refiner_step,
    root_trajectory,
)
from course_lib.skeleton import Skeleton

__all__ = ["check_fraction_left", "check_refiner_round", "check_sample_step", "check_sigma_floor", "fraction_left",
           "refiner_round", "sample_step", "sigma_floor_nll", "tiny_gmm_rnn", "tiny_refiner"]


# ----------------------------------------------------------------------------- reference answers


def sigma_floor_nll(min_std: float, columns: int) -> float:
    """The lowest NLL (nats) that ``columns`` never-varying columns reach when each sits on a component's mean with
    sigma at the floor: columns * (log min_std + log(2 pi) / 2)."""
    return columns * (math.log(min_std) + 0.5 * math.log(2 * math.pi))


def sample_step(model, x_t, state, generator, bias, noise_scale, limits, stats):
    """GmmRnn.sample_step written out: eq. (5) one frame, then eq. (6)-(7) sampled with the bias b and the
    per-column noise scale, the fixed columns copied, the joint limits clamped, the bits made binary."""
    params, state = model(x_t[:, None], state)
    p = {k: v[:, -1] for k, v in params.items()}
    w = torch.softmax((1.0 + bias) * p["logits"], dim=-1)  # sharper weights (Graves eq. 61)
    i = torch.multinomial(w, 1, generator=generator)[:, 0]  # 1. the component
    rows = torch.arange(len(i))
    mu, sigma = p["mu"][rows, i], (p["log_sigma"][rows, i] - bias).exp()  # narrower spread (Graves eq. 62)
    eps = torch.randn(mu.shape, generator=generator, dtype=mu.dtype)  # 2. the draw
    x = mu + sigma * (eps if noise_scale is None else eps * noise_scale)
    c = model.config
    if c.bernoulli_contacts:  # 3. the bits
        prob = torch.sigmoid((1.0 + bias) * p["contact_logits"])
        bits = (torch.rand(prob.shape, generator=generator, dtype=prob.dtype) < prob).to(x.dtype)
        cols = list(c.contact_dims)
        x[:, cols] = (bits - model.feature_mean[cols]) / model.feature_std[cols]
    x[:, list(c.fixed_dims)] = x_t[:, list(c.fixed_dims)]  # not modelled: carried over
    if limits is not None:
        x = torch.clamp(x, limits[0], limits[1])  # joint limits
    return model.fix_contacts(x, stats), state


def fraction_left(capacity: int, replaced: int, updates: int) -> float:
    """Expected fraction of a HistoryBuffer's initial entries left after `updates` replacements of `replaced`
    distinct random entries each: every update keeps a given entry with probability 1 - replaced / capacity."""
    return (1.0 - replaced / capacity) ** updates


def refiner_round(R, D, opt_r, opt_d, buffer, rnn_batches, real) -> dict:
    """One round of sec. 4.2.2: an R update (eq. 9, 13 + the pose terms) on each batch but the last, then one
    D update (eq. 10 halved) on the last batch's refined half + as many buffered motions, against real."""
    c, legs = R.config, leg_columns(R.skeleton)
    r_losses = []
    for x, off in rnn_batches[:-1]:
        refined = R(x, off)
        adversarial = F.softplus(-D.logits(R.discriminator_input(refined, off))).mean()  # -log D(R(x)), eq. (9)
        root = ((root_trajectory(R.raw(x))[0] - root_trajectory(R.raw(refined))[0]) ** 2).sum(-1).mean()
        pose = ((refined - x)[..., list(c.pose_dims)] ** 2).mean()
        leg = ((refined - x)[..., legs] ** 2).mean()
        loss = adversarial + c.lam * root + c.pose_lam * pose + c.leg_pose_lam * leg  # eq. (13) + SimGAN's term
        opt_r.zero_grad()
        loss.backward()
        opt_r.step()
        r_losses.append(float(loss.detach()))
    (x, off), (x_real, off_real), half = rnn_batches[-1], real, c.d_batch // 2
    with torch.no_grad():  # D's update sends no gradient to R
        current = R.discriminator_input(R(x[:half], off[:half]), off[:half])
        fake = buffer.discriminator_batch(current)  # half now, half from the history
        real_in = R.discriminator_input(x_real, off_real)
    d_loss = 0.5 * (F.softplus(D.logits(fake)).mean() + F.softplus(-D.logits(real_in)).mean())  # eq. (10) halved
    opt_d.zero_grad()
    d_loss.backward()
    opt_d.step()
    buffer.replace(current)
    return {"refiner_losses": r_losses, "d_loss": float(d_loss.detach())}


# ----------------------------------------------------------------------------- small models for the checks


def tiny_gmm_rnn(seed: int = 0) -> tuple[GmmRnn, tuple, tuple]:
    """A small GMM-RNN as the lesson's is built (residual angles, fixed columns, Bernoulli bits, joint limits)
    -> (model, its normalised limits (low, high), its stats (mean, std))."""
    torch.manual_seed(seed)
    cfg = GmmRnnConfig.cpu(fc_width=16, lstm_width=16, out_width=16, mixtures=3, absolute_dims=(0, 1, 3, 4, 5),
                           fixed_dims=(8, 9, 20), bernoulli_contacts=True)
    g = torch.Generator().manual_seed(seed)
    mean = 0.1 * torch.randn(68, generator=g, dtype=torch.float64)
    std = 0.5 + torch.rand(68, generator=g, dtype=torch.float64)
    mean[66:], std[66:] = 0.5, 0.5
    model = GmmRnn(cfg, stats=(mean.numpy(), std.numpy())).eval()
    low, high = torch.full((68,), -math.inf), torch.full((68,), math.inf)
    low[6:66], high[6:66] = -1.0, 1.0
    model.set_limits(low, high)
    return model, model.limits(), (model.feature_mean.double(), model.feature_std.double())


def tiny_refiner(seed: int = 0):
    """A small contact-aware R and D (GAN2's recipe at toy widths), their optimisers and a filled history buffer."""
    cfg = RefinerConfig.cpu(fc_width=16, lstm_width=16, d_fc_width=8, d_lstm_width=8, contacts=True,
                            discriminator_contacts=True, pose_lam=10.0, leg_pose_lam=30.0, d_batch=8, buffer_size=12,
                            residual_init_scale=1.0)  # R starts far from the identity: every term counts
    g = torch.Generator().manual_seed(100 + seed)
    mean = torch.zeros(68)
    mean[3], mean[66:] = 0.9, 0.5
    std = 0.2 + 0.1 * torch.rand(68, generator=g)
    torch.manual_seed(seed)
    R, D = Refiner(cfg, stats=(mean.numpy(), std.numpy())), Discriminator(cfg)
    opt_r = torch.optim.RMSprop(R.parameters(), lr=cfg.lr_refiner, alpha=cfg.rmsprop_decay)
    opt_d = torch.optim.RMSprop(D.parameters(), lr=cfg.lr_discriminator, alpha=cfg.rmsprop_decay)
    buffer = HistoryBuffer(cfg.buffer_size, torch.Generator().manual_seed(seed))
    with torch.no_grad():
        buffer.fill(R.discriminator_input(0.5 * torch.randn(cfg.buffer_size, 8, 68, generator=g)))
    return R, D, opt_r, opt_d, buffer


def _batches(r: int, seed: int = 0):
    """r + 1 fixed batches of RNN motions (4, 8, 68) with their rest offsets, and one real batch."""
    g = torch.Generator().manual_seed(200 + seed)
    off = torch.as_tensor(Skeleton.canonical().offsets, dtype=torch.float32).expand(4, -1, -1).clone()
    draw = lambda: (0.5 * torch.randn(4, 8, 68, generator=g), off)  # noqa: E731
    return [draw() for _ in range(r + 1)], draw()


# ----------------------------------------------------------------------------- checks


def check_sigma_floor(fn) -> None:
    """fn(min_std, columns) -> the lowest NLL those columns reach; compared with -mixture_log_prob at the floor."""
    for min_std, n in ((0.01, 24), (0.1, 3), (0.05, 1)):
        x = torch.zeros(n, dtype=torch.float64)
        lib = float(-mixture_log_prob(x, torch.zeros(1, dtype=torch.float64), x[None],
                                      torch.full((1, n), math.log(min_std), dtype=torch.float64)))
        mine = float(fn(min_std, n))
        if abs(mine - lib) < 1e-9:
            continue
        hint = ""
        if abs(mine - n * math.log(min_std)) < 1e-9:
            hint = ": did you drop the log(2 pi) / 2 of the Gaussian's normaliser?"
        elif abs(mine + lib) < 1e-9:
            hint = ": the sign is flipped (a narrow Gaussian's density exceeds 1, so its NLL is negative)"
        elif abs(mine - lib / n) < 1e-9:
            hint = ": that is one column; the columns' NLLs add up"
        raise AssertionError(f"sigma floor {min_std}, {n} columns: got {mine:.4f} nats, the mixture's NLL at its "
                             f"mean is {lib:.4f}{hint}")


def check_sample_step(fn) -> float:
    """fn(model, x_t, state, generator, bias, noise_scale, limits, stats) -> (x_next, state), run for 6 steps on a
    small GMM-RNN against GmmRnn.sample_step on the same seed -> the largest difference."""
    model, limits, stats = tiny_gmm_rnn()
    scale = torch.ones(68)
    scale[6:66] = 0.3
    x0 = 0.3 * torch.randn(5, 68, generator=torch.Generator().manual_seed(7))
    x0 = model.fix_contacts(x0, stats)

    def run(step, bias=2.0, noise=scale, lim=limits):
        g, x, state, out = torch.Generator().manual_seed(3), x0.clone(), None, []
        with torch.no_grad():
            for _ in range(6):
                x, state = step(x, state, g, bias, noise, lim)
                out.append(torch.as_tensor(x, dtype=torch.float32).clone())
        return torch.stack(out)

    def lib(x, state, g, bias, noise, lim):
        return model.sample_step(x, state, g, stats, bias=bias, noise_scale=noise, limits=lim)

    want = run(lib)
    mine = run(lambda x, s, g, b, n, lim: fn(model, x, s, g, b, n, lim, stats))
    assert mine.shape == want.shape, f"x_next must be (N, D) = {tuple(want.shape[1:])}, got {tuple(mine.shape[1:])}"
    diff = float((mine - want).abs().max())
    if diff < 1e-5:
        return diff
    if float((mine[0] - x0).abs().max()) < 1e-6:
        raise AssertionError("your x_next equals x_t: the placeholder is still there (sample the mixture)")
    for label, kw in (("the bias b (logits times 1 + b, log sigma minus b)", {"bias": 0.0}),
                      ("the noise scale (0.3 on the joint angles)", {"noise": None}),
                      ("the joint limits (clamp to limits)", {"lim": None})):
        if float((mine - run(lib, **kw)).abs().max()) < 1e-5:
            raise AssertionError(f"your samples are the library's without {label}")
    fixed = list(model.config.fixed_dims)
    if float((mine[0][:, fixed] - x0[:, fixed]).abs().max()) > 1e-6:
        raise AssertionError("the fixed columns (model.config.fixed_dims) must be copied from x_t")
    raise AssertionError(f"your samples differ from GmmRnn.sample_step by up to {diff:.3g}: draw from the generator "
                         "in the library's order (the component with torch.multinomial, then eps with torch.randn of "
                         "mu's shape, then the bits with torch.rand)")


def check_fraction_left(fn) -> None:
    """fn(capacity, replaced, updates) -> fraction: the formula on three settings, and a HistoryBuffer run."""
    for B, r, u in ((320, 16, 100), (100, 10, 5), (50, 1, 30)):
        mine, want = float(fn(B, r, u)), fraction_left(B, r, u)
        hint = ""
        if abs(mine - (1 - u * r / B)) < 1e-9:
            hint = ": replacements fall on entries already replaced, so the losses compound"
        assert abs(mine - want) < 1e-9, f"B={B}, {r} replaced per update, {u} updates: got {mine:.4f}{hint}"
    buf = HistoryBuffer(320, torch.Generator().manual_seed(0))
    buf.fill(torch.zeros(320, 1))
    for _ in range(100):
        buf.replace(torch.ones(16, 1))
    measured, want = float((buf.data == 0).float().mean()), fraction_left(320, 16, 100)
    sd = math.sqrt(want * (1 - want) / 320)
    assert abs(measured - want) < 4 * sd, f"the buffer keeps {measured:.3f}, the formula says {want:.3f}"


def check_refiner_round(fn, r: int = 3) -> float:
    """fn(R, D, opt_r, opt_d, buffer, rnn_batches, real) -> {"refiner_losses": [r floats], "d_loss": float}, run on
    small models and fixed batches against the library's updates (models/refiner.py) -> the largest difference of
    the parameters after the round."""
    batches, real = _batches(r)
    mine_models = tiny_refiner()
    lib_models = tiny_refiner()
    R, D, opt_r, opt_d, buffer = lib_models
    lib_terms = [_refiner_step(R, D, opt_r, b, R.config.lam, adversarial=True) for b in batches[:-1]]
    lib_d = _discriminator_step(R, D, opt_d, buffer, batches[-1], real, R.config.d_batch // 2)["d_loss"]
    out = fn(*mine_models, copy.deepcopy(batches), copy.deepcopy(real))
    assert isinstance(out, dict) and {"refiner_losses", "d_loss"} <= set(out), \
        "return {'refiner_losses': [one loss per R update], 'd_loss': D's loss}"
    losses = [float(v) for v in out["refiner_losses"]]
    assert len(losses) == r, f"{r + 1} batches make {r} R updates (the last batch is D's), got {len(losses)} losses"
    t = lib_terms[0]
    first, want = losses[0], t["loss"]
    if abs(first - want) > 1e-5 * max(1.0, abs(want)):
        c = mine_models[0].config
        hints = {"the pose terms (mu pose + mu_legs legs)": t["adversarial"] + c.lam * t["root"],
                 "lambda on the root term": t["adversarial"] + t["root"] + c.pose_lam * t["pose"]
                 + c.leg_pose_lam * t["legs"],
                 "the leg term (mu_legs)": want - c.leg_pose_lam * t["legs"],
                 "the adversarial term -log D(R(x))": want - t["adversarial"]}
        why = next((k for k, v in hints.items() if abs(first - v) < 1e-5 * max(1.0, abs(v))), None)
        raise AssertionError(f"R's first loss is {first:.6f}, eq. (13) + the pose terms give {want:.6f}"
                             + (f": it matches a loss without {why}" if why else
                                f" (adversarial {t['adversarial']:.4f}, root {t['root']:.3g}, pose {t['pose']:.3g}, "
                                f"legs {t['legs']:.3g})"))
    d = float(out["d_loss"])
    if abs(d - lib_d) > 1e-5:
        hint = ": did you forget the 1/2 (eq. 10 halved, the mean cross-entropy)?" if abs(d - 2 * lib_d) < 1e-5 else \
            ": D's batch is the refined half plus as many motions from the buffer, against the real batch"
        raise AssertionError(f"D's loss is {d:.6f}, the library's {lib_d:.6f}{hint}")
    pairs = ((mine_models[0], lib_models[0]), (mine_models[1], lib_models[1]))
    diff = max(float((p - q).detach().abs().max()) for a, b in pairs
               for p, q in zip(a.parameters(), b.parameters(), strict=True))
    assert diff < 1e-5, (f"the losses match but the parameters after the round differ by {diff:.3g}: one "
                         "optimiser step per loss, zero_grad before each backward, and no gradient from D's update "
                         "to R (torch.no_grad)")
    buf_diff = float((mine_models[4].data - lib_models[4].data).abs().max())
    assert buf_diff < 1e-5, "after D's update, replace b/2 buffer entries with the refined half (buffer.replace)"
    return diff
