"""Distribution metrics: FID and Inception Score (Ghorbani et al. 2020, eq. 27-29) and a two-sample test.

FID and IS compare *sets* of motions through a pretrained motion classifier
(`course_lib.evaluation.classifiers`, Ghorbani's Table 1 Conv1D network): FID
uses its penultimate-layer features, IS its class probabilities.  Inputs are
either lists of Motions, ``(N, T, C)`` arrays in the classifier's input
representation, or already-computed ``(N, F)`` features / ``(N, K)`` probabilities.

Taught in notebooks/05_hierarchical_vrnn.ipynb and notebooks/07_benchmark.ipynb.

Differs from the paper:
- Ghorbani et al. use one classifier per attribute trained on AMASS; ours are
  trained on the synthetic data of the course, so values are not comparable
  with their Table 2 (real data: IS 7.64 for 8 attribute combinations, FID 0),
  only the ordering of models is.
- The two-sample classifier test is not in the paper: a logistic regression on
  per-channel summary statistics, trained on one half and tested on the other
  half, then the halves swapped (2-fold) to halve the variance.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.optimize
import scipy.special
import torch

from course_lib.evaluation.classifiers import MotionClassifier, load_classifier, motions_to_batch
from course_lib.motion import Motion

__all__ = ["classifier_features", "fid", "frechet_distance", "inception_score", "summary_features",
           "two_sample_accuracy"]


def _array(x, name: str) -> np.ndarray:
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    x = np.asarray(x, dtype=np.float64)
    if not np.isfinite(x).all():
        raise ValueError(f"{name}: contains NaN or inf values")
    return x


def _is_motions(x) -> bool:
    return isinstance(x, (list, tuple)) and len(x) > 0 and all(isinstance(m, Motion) for m in x)


def classifier_features(x, classifier: MotionClassifier, name: str = "x", kind: str = "features") -> np.ndarray:
    """Motions or (N, T, C) inputs -> (N, F) penultimate features (kind='features') or (N, K) probabilities."""
    if _is_motions(x):
        x = motions_to_batch(x, classifier.config)
    arr = _array(x, name)
    if arr.ndim != 3 or arr.shape[-1] != classifier.config.in_channels:
        raise ValueError(f"{name}: expected Motions or (N, T, {classifier.config.in_channels}) classifier inputs, "
                         f"got shape {arr.shape}")
    with torch.no_grad():
        inp = torch.from_numpy(arr).float()
        out = classifier.features(inp) if kind == "features" else torch.softmax(classifier(inp), -1)
    return out.double().numpy()


def frechet_distance(mu1: np.ndarray, sigma1: np.ndarray, mu2: np.ndarray, sigma2: np.ndarray) -> float:
    """||mu1 - mu2||^2 + Tr(S1 + S2 - 2 (S1 S2)^(1/2))  -- Ghorbani eq. (29); (F,), (F, F) x 2 -> float.

    Tr (S1 S2)^(1/2) = sum_i sqrt(lambda_i) with lambda_i the eigenvalues of the symmetric PSD
    matrix S1^(1/2) S2 S1^(1/2) (same spectrum as S1 S2), so no complex sqrtm is needed.
    """
    w1, v1 = np.linalg.eigh((sigma1 + sigma1.T) / 2)
    s1_half = (v1 * np.sqrt(np.clip(w1, 0, None))) @ v1.T
    lam = np.linalg.eigvalsh(s1_half @ sigma2 @ s1_half)
    tr_sqrt = np.sqrt(np.clip(lam, 0, None)).sum()
    # clipped at 0: for (near) identical sets round-off can give a tiny negative value
    return max(0.0, float(((mu1 - mu2) ** 2).sum() + np.trace(sigma1) + np.trace(sigma2) - 2 * tr_sqrt))


def _features_2d(x, classifier, name: str) -> np.ndarray:
    arr = None if _is_motions(x) else _array(x, name)
    if arr is not None and arr.ndim == 2:
        return arr
    return classifier_features(x, classifier, name)


def fid(real, generated, classifier: MotionClassifier | None = None) -> float:
    """Frechet distance between classifier features of real and generated motions (Ghorbani eq. 29).

    real, generated: Motions, (N, T, C) classifier inputs, or (N, F) features -> float (>= 0,
    0 for identical sets).  classifier: default the shipped action classifier.  The Gaussians
    N(mu, Sigma) are fitted to the features of the last layer before the final FC layer.
    """
    classifier = classifier or load_classifier("action")
    fr = _features_2d(real, classifier, "real")
    fg = _features_2d(generated, classifier, "generated")
    if fr.shape[1] != fg.shape[1]:
        raise ValueError(f"fid: real and generated features differ in size ({fr.shape[1]} vs {fg.shape[1]})")
    if min(len(fr), len(fg)) < 2:
        raise ValueError(f"fid: needs at least 2 samples per set, got {len(fr)} real and {len(fg)} generated")
    return frechet_distance(fr.mean(0), np.cov(fr, rowvar=False), fg.mean(0), np.cov(fg, rowvar=False))


def inception_score(generated, classifier: MotionClassifier | None = None) -> float:
    """IS = exp( 1/M sum_i KL(p(a|X_i) || p_hat(a)) ),  p_hat(a) = 1/M sum_i p(a|X_i)  -- Ghorbani eq. (27-28).

    generated: Motions, (N, T, C) classifier inputs, or (N, K) class probabilities -> float in
    [1, K]: K when the classifier is sure of every sample and the classes are balanced, 1 when
    every sample gets the same distribution.  classifier: default the shipped action classifier.
    """
    arr = None if _is_motions(generated) else _array(generated, "generated")
    if arr is not None and arr.ndim == 2:
        if (arr < 0).any() or np.abs(arr.sum(1) - 1).max() > 1e-4:
            raise ValueError("inception_score: (N, K) inputs must be probabilities (non-negative, rows sum to 1)")
        p = arr
    else:
        p = classifier_features(generated, classifier or load_classifier("action"), "generated", kind="proba")
    logp = np.log(np.clip(p, 1e-12, None))  # (M, K)
    log_marginal = np.log(np.clip(p.mean(0), 1e-12, None))  # (K,)
    kl = (p * (logp - log_marginal)).sum(1)  # (M,)
    return float(np.exp(kl.mean()))


# ----------------------------------------------------------------------------- two-sample test


def summary_features(x: np.ndarray) -> np.ndarray:
    """(N, T, C) sequences -> (N, 3C): per-channel mean, std over time, and mean |frame difference|."""
    x = _array(x, "x")
    if x.ndim != 3 or x.shape[1] < 2:
        raise ValueError(f"summary_features: expected (N, T, C) with T >= 2, got shape {x.shape}")
    return np.concatenate([x.mean(1), x.std(1), np.abs(np.diff(x, axis=1)).mean(1)], -1)


def _logistic_accuracy(xa, ya, xb, yb, l2: float, steps: int) -> float:
    """Fit L2-regularised logistic regression on (xa, ya) (scipy L-BFGS), return its accuracy on (xb, yb)."""
    mu, sd = xa.mean(0), xa.std(0) + 1e-8
    xa, xb = (xa - mu) / sd, (xb - mu) / sd
    A = np.column_stack([xa, np.ones(len(xa))])  # last weight is the bias (not penalised)
    mask = np.r_[np.ones(xa.shape[1]), 0.0]

    def loss_grad(w):
        z = A @ w
        # mean BCE with logits: log(1 + e^z) - y z, written stably with logaddexp
        loss = np.logaddexp(0.0, z).mean() - (ya * z).mean() + l2 * (mask * w * w).sum()
        grad = A.T @ (scipy.special.expit(z) - ya) / len(z) + 2 * l2 * mask * w
        return loss, grad

    w = scipy.optimize.minimize(loss_grad, np.zeros(A.shape[1]), jac=True, method="L-BFGS-B",
                                options={"maxiter": steps}).x
    pred = np.column_stack([xb, np.ones(len(xb))]) @ w > 0
    return float((pred == yb.astype(bool)).mean())


def two_sample_accuracy(real, generated, seed: int = 0, features: Callable | None = None,
                        l2: float = 0.1, steps: int = 200) -> float:
    """Held-out accuracy of a classifier told to separate real from generated samples, in [0, 1].

    real, generated: (N, F) feature arrays, (N, T, C) sequences (reduced by ``features``,
    default `summary_features`), or Motions (encoded like the classifiers' inputs first).
    Each set is shuffled (``seed``) and halved; a logistic regression is trained on one half
    of both and tested on the other, then the halves swap; the mean accuracy is returned.
    ~0.5: the sets are indistinguishable to this test; ~1.0: trivially separable.
    """
    xr, xg = (_two_sample_input(x, name, features) for x, name in ((real, "real"), (generated, "generated")))
    if xr.shape[1] != xg.shape[1]:
        raise ValueError(f"two_sample_accuracy: feature sizes differ ({xr.shape[1]} vs {xg.shape[1]})")
    if min(len(xr), len(xg)) < 4:
        raise ValueError(f"two_sample_accuracy: needs >= 4 samples per set, got {len(xr)} and {len(xg)}")
    rng = np.random.default_rng(seed)
    n = min(len(xr), len(xg))  # balanced classes: chance is exactly 0.5
    xr, xg = xr[rng.permutation(len(xr))[:n]], xg[rng.permutation(len(xg))[:n]]
    half = n // 2
    folds = [(slice(0, half), slice(half, n)), (slice(half, n), slice(0, half))]
    accs = []
    for tr, te in folds:
        xa, ya = np.concatenate([xr[tr], xg[tr]]), np.r_[np.zeros(len(xr[tr])), np.ones(len(xg[tr]))]
        xb, yb = np.concatenate([xr[te], xg[te]]), np.r_[np.zeros(len(xr[te])), np.ones(len(xg[te]))]
        accs.append(_logistic_accuracy(xa, ya, xb, yb, l2, steps))
    return float(np.mean(accs))


def _two_sample_input(x, name: str, features: Callable | None) -> np.ndarray:
    if _is_motions(x):
        from course_lib.evaluation.classifiers import ClassifierConfig

        x = motions_to_batch(x, ClassifierConfig())
    arr = _array(x, name)
    if arr.ndim == 3:
        arr = _array((features or summary_features)(arr), name)
    if arr.ndim != 2:
        raise ValueError(f"{name}: expected (N, F) features, (N, T, C) sequences or Motions, got shape {arr.shape}")
    return arr
