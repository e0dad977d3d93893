"""How often each CFAR detector fires on noise: its false-alarm probability as a function of its
scale alpha, and the scale solved for a Pfa; the noise estimate's mean against the noise's.

The formulas (cell under test ``power > alpha * noise estimate``; ``n`` training cells, or
``n`` a side for CAGO and CASO):

- CA (Finn & Johnson 1968; Richards, *Fundamentals of Radar Signal Processing*, 2nd ed.,
  sec. 16.4): ``Pfa = (1 + alpha / n) ** -n``;
- CASO and CAGO with T = alpha / n the factor on a side's sum (Weiss 1982, IEEE TAES 18(1);
  Gandhi & Kassam 1988, IEEE TAES 24(4)), exact:
  ``Pfa_SO(T) = 2 (2 + T) ** -n * sum_{j=0}^{n-1} C(n - 1 + j, j) (2 + T) ** -j`` and
  ``Pfa_GO(T) = 2 (1 + T) ** -n - Pfa_SO(T)``;
- OS (Rohling 1983, IEEE TAES 19(4)), the k-th smallest of n:
  ``Pfa = prod_{i=0}^{k-1} (n - i) / (n - i + alpha)``;
- cells that sum the powers of several independent channels (Gamma(channels) noise) and a
  real-valued ``n`` (the independent-cell worth of correlated training cells,
  CfarParams.effective_cells): one-dimensional integrals (:func:`log_pfa_summed`).

Scales are solved by Brent's method on log Pfa.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from .kept_scales import kept


def log_pfa_ca(alpha: float, n: int) -> float:
    """log Pfa of CA-CFAR over *n* cells, threshold ``alpha * mean``."""
    return -n * math.log1p(alpha / n)


def log_pfa_so(alpha: float, n: int) -> float:
    """log Pfa of CASO with *n* cells a side, threshold ``alpha * min(side means)``."""
    from scipy.special import gammaln, logsumexp

    t = alpha / n
    j = np.arange(n, dtype=np.float64)
    log_terms = gammaln(n + j) - gammaln(j + 1.0) - gammaln(float(n)) - j * math.log(2.0 + t)
    return math.log(2.0) - n * math.log(2.0 + t) + float(logsumexp(log_terms))


def log_pfa_go(alpha: float, n: int) -> float:
    """log Pfa of CAGO with *n* cells a side, threshold ``alpha * max(side means)``."""
    t = alpha / n
    both = 2.0 * math.exp(-n * math.log1p(t))  # 2 * Pfa of CA over one side
    so = math.exp(log_pfa_so(alpha, n))
    return math.log(max(both - so, 1e-300))


def log_pfa_os(alpha: float, n: int, k: int) -> float:
    """log Pfa of OS-CFAR over *n* cells, threshold ``alpha * (k-th smallest)``."""
    m = n - np.arange(k, dtype=np.float64)
    return float(np.sum(np.log(m) - np.log(m + alpha)))


def log_pfa_summed(alpha: float, method: str, n: int, channels: int, k: int | None = None) -> float:
    """log Pfa when every cell is the sum of *channels* independent exponential
    powers (a Gamma(channels) variable), as a map summed over virtual antennas is.

    CA (n cells): the cell over the training mean is F(2L, 2nL) distributed, so
    Pfa = I_{n/(n+alpha)}(nL, L) (regularized incomplete beta).  CASO/CAGO (n cells
    a side): Pfa = E[Q(L, alpha S / n)] over S the smaller / larger of two Gamma(nL)
    side sums; OS (n cells, rank k): the same over the k-th smallest of n Gamma(L)
    cells; Q is the regularized upper incomplete gamma function.  The expectations
    are one-dimensional integrals.
    """
    import scipy.integrate
    from scipy.special import betainc, gammainc, gammaincc, gammaln

    L = float(channels)
    if method == "ca":
        return math.log(max(float(betainc(n * L, L, n / (n + alpha))), 1e-300))
    if method in ("caso", "cago"):
        a = n * L  # each side's sum is Gamma(nL)

        def density(s):
            pdf = np.exp((a - 1) * np.log(s) - s - gammaln(a))
            other = gammaincc(a, s) if method == "caso" else gammainc(a, s)
            return 2 * pdf * other
        scale, upper = alpha / n, a + 40 * math.sqrt(a) + 40
    else:  # os: the k-th smallest of n Gamma(L) cells
        log_c = gammaln(n + 1) - gammaln(k) - gammaln(n - k + 1)

        def density(y):
            log_pdf = (L - 1) * np.log(y) - y - gammaln(L)
            return np.exp(log_c + (k - 1) * np.log(gammainc(L, y)) + (n - k) * np.log(gammaincc(L, y)) + log_pdf)
        scale, upper = alpha, L + 40 * math.sqrt(L) + 40
    value, _ = scipy.integrate.quad(lambda s: density(s) * gammaincc(L, scale * s), 1e-12, upper,
                                    limit=200, epsabs=0.0, epsrel=1e-9)
    return math.log(max(value, 1e-300))


@kept
def summed_scale(method: str, n: int, channels: int, k: int | None, pfa: float) -> float:
    """The solved alpha for summed noise (kept on disk: :mod:`.kept_scales`)."""
    return solve_alpha(lambda a: log_pfa_summed(a, method, n, channels, k), pfa)


@kept
def ordered_scale(n: int, k: int, pfa: float) -> float:
    """The solved alpha of OS-CFAR, rank *k* of *n* cells (kept on disk)."""
    return solve_alpha(lambda a: log_pfa_os(a, n, k), pfa)


@kept
def split_scale(method: str, side: int, pfa: float) -> float:
    """The solved alpha of CAGO or CASO (*method*) with *side* cells a side (kept on disk)."""
    fn = log_pfa_go if method == "cago" else log_pfa_so
    return solve_alpha(lambda a: fn(a, side), pfa)


@kept
def noise_factor(method: str, side: float, channels: int, rank: float | None) -> float:
    """E[noise estimate] / E[cell power] for independent Gamma(channels) cells, *side* cells a
    side (independent-cell worth), OS rank *rank* of 2 * side."""
    from scipy.special import gammainc, gammaincc, gammaln

    if method == "ca":
        return 1.0
    import scipy.integrate

    L = float(channels)
    if method in ("cago", "caso"):
        a = side * L  # a side's mean: Gamma(a) scaled to unit mean
        scale = 1.0 / a

        def cdf(x):  # scipy.stats.gamma(a, scale=scale).cdf, without importing scipy.stats
            return gammainc(a, x / scale)

        def integrand(x):  # E[max] = int 1 - F^2, E[min] = int (1 - F)^2
            f = cdf(x)
            return 1.0 - f * f if method == "cago" else (1.0 - f) ** 2
        upper = 1.0 + 40.0 / math.sqrt(a)
    else:
        n, k = 2.0 * side, rank
        log_c = gammaln(n + 1) - gammaln(k) - gammaln(n - k + 1)

        def integrand(x):  # x times the k-th order statistic's density, cells of unit mean
            y = L * x
            below, above = gammainc(L, y), gammaincc(L, y)
            if below <= 0.0 or above <= 0.0:
                return 0.0
            log_pdf = math.log(L) + (L - 1) * math.log(y) - y - gammaln(L)
            return x * math.exp(log_c + (k - 1) * math.log(below) + (n - k) * math.log(above) + log_pdf)
        upper = 1.0 + 40.0 / math.sqrt(L)
    value, _ = scipy.integrate.quad(integrand, 1e-12, upper, limit=200)
    return float(value)


def solve_alpha(log_pfa, pfa: float) -> float:
    """The alpha > 0 where the decreasing function ``log_pfa(alpha)`` equals log(pfa)."""
    from scipy.optimize import brentq

    target = math.log(pfa)
    hi = 1.0
    while log_pfa(hi) > target:  # bracket the root: Pfa falls monotonically in alpha
        hi *= 2.0
        if hi > 1e300:
            raise ConfigError(f"no finite scale reaches Pfa {pfa:g}", command="CfarParams", field="pfa")
    return float(brentq(lambda a: log_pfa(a) - target, 0.0, hi, xtol=1e-14, rtol=1e-13))



__all__ = ["log_pfa_ca", "log_pfa_go", "log_pfa_os", "log_pfa_so", "log_pfa_summed", "noise_factor", "ordered_scale",
           "solve_alpha", "split_scale", "summed_scale"]
