"""Distribution metrics: FID and Inception Score (Ghorbani et al. 2020, eq. 27-29) and the classifier two-sample test.

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
- The classifier two-sample test (C2ST, Lopez-Paz and Oquab 2017) is not in the
  paper: a logistic regression in the same classifier features (action and style
  side by side), 5-fold, with a 95 % Wilson interval on its held-out accuracy.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize
import scipy.special
import torch

from course_lib.evaluation.classifiers import MotionClassifier, load_classifier, motions_to_batch
from course_lib.motion import Motion

__all__ = ["c2st", "classifier_features", "fid", "frechet_distance", "inception_score", "wilson_interval"]


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
    return classifier_features(x, classifier or load_classifier("action"), name)  # loaded only when needed


def fid(real, generated, classifier: MotionClassifier | None = None) -> float:
    """Frechet distance between classifier features of real and generated motions (Ghorbani eq. 29).

    real, generated: Motions, (N, T, C) classifier inputs, or (N, F) features -> float (>= 0,
    0 for identical sets).  classifier: default the shipped action classifier.  The Gaussians
    N(mu, Sigma) are fitted to the features of the last layer before the final FC layer.
    """
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


def _c2st_features(x, classifiers, name: str) -> np.ndarray:
    """Motions / (N, T, C) inputs -> (N, sum F) the classifiers' features side by side; (N, F) unchanged."""
    arr = None if _is_motions(x) else _array(x, name)
    if arr is not None and arr.ndim == 2:
        return arr
    return np.concatenate([classifier_features(x, clf, name) for clf in classifiers], 1)


def _fit_logistic(x: np.ndarray, y: np.ndarray, l2: float, steps: int):
    """L2-regularised logistic regression (scipy L-BFGS) on standardised x (M, F), y (M,) in {0, 1}
    -> predict(x) -> (M',) bool, True for class 1."""
    mu, sd = x.mean(0), x.std(0) + 1e-8
    A = np.column_stack([(x - mu) / sd, np.ones(len(x))])  # last weight is the bias (not penalised)
    mask = np.r_[np.ones(x.shape[1]), 0.0]

    def loss_grad(w):
        z = A @ w
        # mean BCE with logits: log(1 + e^z) - y z, written stably with logaddexp
        loss = np.logaddexp(0.0, z).mean() - (y * z).mean() + l2 * (mask * w * w).sum()
        grad = A.T @ (scipy.special.expit(z) - y) / len(z) + 2 * l2 * mask * w
        return loss, grad

    w = scipy.optimize.minimize(loss_grad, np.zeros(A.shape[1]), jac=True, method="L-BFGS-B",
                                options={"maxiter": steps}).x
    return lambda xb: np.column_stack([(xb - mu) / sd, np.ones(len(xb))]) @ w > 0


def wilson_interval(correct: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion correct / n (95 % for z = 1.96) -> (low, high)."""
    if n < 1 or not 0 <= correct <= n:
        raise ValueError(f"wilson_interval: need 0 <= correct <= n and n >= 1, got {correct} of {n}")
    p = correct / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return float(centre - half), float(centre + half)


def c2st(real, generated, seed: int = 0, classifiers=None, folds: int = 5, l2: float = 0.01,
         steps: int = 300) -> dict:
    """Classifier two-sample test (Lopez-Paz and Oquab 2017) in the shared classifier features.

    real, generated: Motions, (N, T, C) classifier inputs, or (N, F) features.  Motions and inputs
    are mapped to the penultimate features of ``classifiers`` side by side (default: the shipped
    action and style classifiers, FID's feature space; 128 values).  Both sets are subsampled to
    the same size n (seeded), so chance is exactly 0.5; a logistic regression trained on the
    other ``folds - 1`` folds (at most n folds) predicts each fold, so every one of the 2n samples is predicted by a
    model that never saw it.  -> {"accuracy": held-out accuracy, "ci_low", "ci_high": its 95 % Wilson
    interval over the 2n predictions, "n": 2n}.  ~0.5: indistinguishable to this test; 1: separable.
    """
    if classifiers is None:
        classifiers = [load_classifier("action"), load_classifier("style")]
    xr, xg = _c2st_features(real, classifiers, "real"), _c2st_features(generated, classifiers, "generated")
    if xr.shape[1] != xg.shape[1]:
        raise ValueError(f"c2st: feature sizes differ ({xr.shape[1]} vs {xg.shape[1]})")
    n = min(len(xr), len(xg))
    if folds < 2 or n < 2:
        raise ValueError(f"c2st: needs folds >= 2 and at least 2 samples per set, got folds={folds}, "
                         f"{len(xr)} real and {len(xg)} generated")
    folds = min(folds, n)  # tiny sets: leave-one-pair-out
    rng = np.random.default_rng(seed)
    x = np.concatenate([xr[rng.permutation(len(xr))[:n]], xg[rng.permutation(len(xg))[:n]]])
    y = np.r_[np.zeros(n), np.ones(n)]
    fold = np.concatenate([rng.permutation(n) % folds, rng.permutation(n) % folds])  # balanced folds
    correct = 0
    for k in range(folds):
        predict = _fit_logistic(x[fold != k], y[fold != k], l2, steps)
        correct += int((predict(x[fold == k]) == y[fold == k].astype(bool)).sum())
    low, high = wilson_interval(correct, 2 * n)
    return {"accuracy": correct / (2 * n), "ci_low": low, "ci_high": high, "n": 2 * n}
