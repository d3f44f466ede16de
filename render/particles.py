"""Bulk optical properties of a host with particles in it, from Lorenz–Mie theory.

The talk's "Bulk optical properties of a material" slide (FCJ07 sec. 4): for each particle
type, a representative number density distribution ``N^(r)`` is scaled to the wanted volume
fraction ``v`` by ``N = N^ v / v^`` with ``v^ = 4 pi / 3 int r^3 N^(r) dr``; then

    sigma_s = sum_types int C_s(r) N(r) dr,       sigma_t = sigma_a,host + sum_types int C_t(r) N(r) dr,
    sigma_a = sigma_t - sigma_s,                   g = sum_types int g(r) C_s(r) N(r) dr / sigma_s,

with the host's absorption ``sigma_a,host = 4 pi kappa_med / lambda`` and, in an absorbing
host, FCJ07's cross sections (which is what makes ``C_t - C_s`` of a clear particle negative:
it displaces absorbing host). The ensemble phase function is the ``C_s N``-weighted mixture of
the particles' phase functions. Everything per wavelength; lengths in micrometres inside,
coefficients returned per millimetre.

Integrals over radius use a log-spaced grid (trapezoid in ``ln r``); the same grid gives
``v^``, so the volume fraction is exactly the one asked for on that grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np

from render import mie

Weighting = Literal["number", "volume"]


class SizeDistribution(Protocol):
    """A particle size distribution: a shape ``N^(r)`` (any scale) and the radii it covers."""

    def support_um(self) -> tuple[float, float]: ...

    def number_density(self, r_um: np.ndarray) -> np.ndarray: ...


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name}: expected a positive finite number, got {value!r}")


def _check_range(name: str, range_um: tuple[float, float] | None) -> None:
    if range_um is None:
        return
    lo, hi = range_um
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo < 0 or hi <= lo:
        raise ValueError(f"{name}: expected radii 0 <= min < max, got [{lo!r}, {hi!r}] um")


@dataclass(frozen=True)
class LogNormal:
    """Log-normal radii: ``ln r`` normal with median ``median_um`` and standard deviation ``sigma``.

    ``weighting = "volume"`` makes it the distribution of particle *volume* over radius (as
    FCJ07's milk model reads its log-normals), so ``N^(r) = f(r) / r^3``. ``bound_um`` makes
    it log-normal in ``t = r / (bound - r)`` instead (FCJ07's casein micelles, radii below
    150 nm), evaluated as FCJ07's implementation does, without the Jacobian ``dt/dr``.
    ``range_um`` limits the radii (default: ``median exp(+-5 sigma)``, or ``(0, bound)``).
    """

    median_um: float
    sigma: float
    weighting: Weighting = "number"
    bound_um: float | None = None
    range_um: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        _positive("median radius", self.median_um)
        _positive("log-normal sigma", self.sigma)
        if self.weighting not in ("number", "volume"):
            raise ValueError(f"weighting: expected 'number' or 'volume', got {self.weighting!r}")
        if self.bound_um is not None:
            _positive("bound", self.bound_um)
        _check_range("range_um", self.range_um)

    @classmethod
    def from_mean_std(
        cls,
        mean: float,
        std: float,
        *,
        weighting: Weighting = "number",
        bound_um: float | None = None,
        range_um: tuple[float, float] | None = None,
    ) -> LogNormal:
        """From the mean and standard deviation of the log-normal variable (FCJ07's ``r_vs``, ``c_s``):
        ``beta^2 = ln(1 + std^2 / mean^2)``, ``alpha = ln(mean) - beta^2 / 2``, median ``exp(alpha)``.

        The variable is ``r`` in micrometres, or ``t = r / (bound - r)`` with ``bound_um``.
        """
        _positive("mean", mean)
        _positive("standard deviation", std)
        beta2 = math.log(1.0 + (std / mean) ** 2)
        median = math.exp(math.log(mean) - 0.5 * beta2)
        if bound_um is not None:
            # The median of t, mapped back to a radius so that median_um stays a radius.
            median = bound_um * median / (1.0 + median)
        return cls(median, math.sqrt(beta2), weighting, bound_um, range_um)

    def support_um(self) -> tuple[float, float]:
        if self.range_um is not None:
            return self.range_um
        if self.bound_um is not None:
            return (0.0, self.bound_um)
        spread = math.exp(5.0 * self.sigma)
        return (self.median_um / spread, self.median_um * spread)

    def number_density(self, r_um: np.ndarray) -> np.ndarray:
        r = np.asarray(r_um, dtype=np.float64)
        if self.bound_um is None:
            t = r
            t_median = self.median_um
        else:
            with np.errstate(divide="ignore"):
                t = np.where(r < self.bound_um, r / np.maximum(self.bound_um - r, 1e-300), np.inf)
            t_median = self.median_um / (self.bound_um - self.median_um)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (np.log(t) - math.log(t_median)) / self.sigma
            pdf = np.where((t > 0) & np.isfinite(t), np.exp(-0.5 * z * z) / (t * self.sigma), 0.0)
        if self.weighting == "volume":
            pdf = pdf / r**3
        return pdf


@dataclass(frozen=True)
class PowerLaw:
    """``N^(r) = r^-exponent`` between ``r_min_um`` and ``r_max_um`` (the talk's natural waters)."""

    r_min_um: float
    r_max_um: float
    exponent: float

    def __post_init__(self) -> None:
        _positive("r_min_um", self.r_min_um)
        _check_range("power law radii", (self.r_min_um, self.r_max_um))
        if not math.isfinite(self.exponent):
            raise ValueError(f"exponent: expected a finite number, got {self.exponent!r}")

    def support_um(self) -> tuple[float, float]:
        return (self.r_min_um, self.r_max_um)

    def number_density(self, r_um: np.ndarray) -> np.ndarray:
        r = np.asarray(r_um, dtype=np.float64)
        inside = (r >= self.r_min_um * (1 - 1e-12)) & (r <= self.r_max_um * (1 + 1e-12))
        return np.where(inside, r ** (-self.exponent), 0.0)


@dataclass(frozen=True)
class Bimodal:
    """Two modes with ``second_fraction`` of the particle volume in the second (the talk's apple
    juice uses such a distribution, after Zimmer et al. 1994)."""

    first: SizeDistribution
    second: SizeDistribution
    second_fraction: float

    def __post_init__(self) -> None:
        if not (0.0 <= self.second_fraction <= 1.0):
            raise ValueError(f"second_fraction: expected a value in [0, 1], got {self.second_fraction!r}")

    def support_um(self) -> tuple[float, float]:
        a, b = self.first.support_um(), self.second.support_um()
        return (min(a[0], b[0]), max(a[1], b[1]))

    def number_density(self, r_um: np.ndarray) -> np.ndarray:
        out = np.zeros(np.shape(r_um))
        for dist, share in ((self.first, 1.0 - self.second_fraction), (self.second, self.second_fraction)):
            if share == 0.0:
                continue
            r, w = radius_grid(dist, 400)
            volume = 4.0 / 3.0 * math.pi * float(np.sum(r**3 * dist.number_density(r) * w))
            out = out + share * dist.number_density(r_um) / volume
        return out


def radius_grid(dist: SizeDistribution, n_radii: int) -> tuple[np.ndarray, np.ndarray]:
    """Radii (um) log-spaced over the distribution's support and trapezoid weights for ``int dr``."""
    lo, hi = dist.support_um()
    if lo <= 0:
        lo = hi * 1e-4  # the radii below carry a negligible share of both volume and scattering
    if n_radii < 2:
        raise ValueError(f"n_radii: expected at least 2, got {n_radii}")
    ln_r = np.linspace(math.log(lo), math.log(hi), n_radii)
    r = np.exp(ln_r)
    step = ln_r[1] - ln_r[0]
    w = np.full(n_radii, step)
    w[0] = w[-1] = step / 2
    return r, w * r


@dataclass(frozen=True)
class Component:
    """One particle type: its index ``n - i kappa`` per wavelength, sizes and volume fraction."""

    name: str
    index: np.ndarray
    distribution: SizeDistribution
    volume_fraction: float


@dataclass
class SpectralOptics:
    """Scattering properties per wavelength (coefficients in 1/mm)."""

    wavelength_nm: np.ndarray
    host_index: np.ndarray
    sigma_s_per_mm: np.ndarray
    sigma_a_per_mm: np.ndarray
    g: np.ndarray
    components: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    _phase_inputs: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=list, repr=False
    )

    @property
    def sigma_t_per_mm(self) -> np.ndarray:
        return self.sigma_s_per_mm + self.sigma_a_per_mm

    @property
    def reduced_scattering_per_mm(self) -> np.ndarray:
        """``sigma_s' = sigma_s (1 - g)`` (the similarity relation)."""
        return self.sigma_s_per_mm * (1.0 - self.g)

    @property
    def transport_mfp_mm(self) -> np.ndarray:
        """Transport mean free path ``1 / (sigma_a + sigma_s')`` (mm): how far light goes before
        its direction is forgotten."""
        with np.errstate(divide="ignore"):
            return 1.0 / (self.sigma_a_per_mm + self.reduced_scattering_per_mm)

    def phase_function(self, mu: np.ndarray, wavelength_index: int) -> np.ndarray:
        """Ensemble phase function (1/sr) at cosines ``mu`` for one of the wavelengths."""
        m, x, n_med, weight = self._phase_inputs[wavelength_index]
        if not np.any(weight > 0):
            return np.full(np.shape(mu), 1.0 / (4.0 * math.pi))
        return mie.phase_function(m, x, mu, n_med, weights=weight)


def bulk_optics(
    wavelength_nm: np.ndarray,
    host_index: np.ndarray,
    components: list[Component],
    n_radii: int = 160,
) -> SpectralOptics:
    """sigma_s, sigma_a and g per wavelength of a host with particles (FCJ07 sec. 4).

    Parameters
    ----------
    wavelength_nm : (k,) array
        Wavelengths in vacuum (nm).
    host_index : (k,) complex array
        The host's index ``n - i kappa`` at those wavelengths.
    components : list of Component
        Particle types; their ``index`` arrays are per wavelength, their volume fractions sum
        to at most 1.
    n_radii : int
        Radius samples per particle type.

    Raises
    ------
    ValueError
        Negative or non-finite volume fractions, fractions summing above 1, bad wavelengths or
        indices, distributions without particles.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    if lam.ndim != 1 or lam.size == 0 or not np.all(np.isfinite(lam)) or np.any(lam <= 0):
        raise ValueError("wavelength_nm: expected a 1-D array of positive wavelengths (nm)")
    host = np.asarray(host_index, dtype=np.complex128)
    if host.shape != lam.shape:
        raise ValueError("host_index: expected one index per wavelength")
    total_fraction = 0.0
    for comp in components:
        v = comp.volume_fraction
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{comp.name}: expected a volume fraction >= 0, got {v!r}")
        total_fraction += v
        if np.shape(comp.index) != lam.shape:
            raise ValueError(f"{comp.name}: expected one particle index per wavelength")
    if total_fraction > 1.0:
        raise ValueError(f"volume fractions: expected a sum of at most 1, got {total_fraction:.6g}")
    k_med = -host.imag
    sigma_a = 4.0 * math.pi * k_med / (lam * 1e-6)  # host absorption, 1/mm
    sigma_s = np.zeros_like(lam)
    scat_g = np.zeros_like(lam)
    per_component: dict[str, dict[str, np.ndarray]] = {}
    phase_parts: list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = [[] for _ in lam]
    for comp in components:
        if comp.volume_fraction == 0.0:
            continue
        r, w = radius_grid(comp.distribution, n_radii)
        shape = comp.distribution.number_density(r)
        if np.any(shape < 0) or not np.all(np.isfinite(shape)):
            raise ValueError(f"{comp.name}: the size distribution has negative or non-finite densities")
        v_hat = 4.0 / 3.0 * math.pi * float(np.sum(r**3 * shape * w))
        if v_hat <= 0:
            raise ValueError(f"{comp.name}: the size distribution holds no particles in its radius range")
        number = shape * comp.volume_fraction / v_hat  # particles per um^3 per um
        n_p = np.asarray(comp.index, dtype=np.complex128)
        m = (n_p / host)[:, None] * np.ones_like(r)[None, :]
        x = 2.0 * math.pi * r[None, :] * host.real[:, None] / lam[:, None] * 1e3
        n_med = host[:, None] * np.ones_like(r)[None, :]
        q_ext, q_sca, _, g = mie.efficiencies(m, x, n_med)
        area = math.pi * r**2  # um^2
        nw = number * w
        c_sca = q_sca * area[None, :] * nw[None, :]  # 1/um per radius sample
        c_ext = q_ext * area[None, :] * nw[None, :]
        s = c_sca.sum(axis=1) * 1e3
        t = c_ext.sum(axis=1) * 1e3
        sg = (c_sca * g).sum(axis=1) * 1e3
        sigma_s += s
        sigma_a += t - s
        scat_g += sg
        per_component[comp.name] = {
            "sigma_s_per_mm": s,
            "sigma_a_per_mm": t - s,
            "g": np.divide(sg, s, out=np.zeros_like(s), where=s > 0),
        }
        for k in range(lam.size):
            phase_parts[k].append((m[k], x[k], n_med[k], c_sca[k]))
    g_mean = np.divide(scat_g, sigma_s, out=np.zeros_like(sigma_s), where=sigma_s > 0)
    phase_inputs = []
    for parts in phase_parts:
        if parts:
            phase_inputs.append(tuple(np.concatenate([p[i] for p in parts]) for i in range(4)))
        else:
            phase_inputs.append((np.ones(1), np.zeros(1), np.ones(1), np.zeros(1)))
    return SpectralOptics(lam, host, sigma_s, sigma_a, g_mean, per_component, phase_inputs)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------
# FCJ07's milk: fat globules and casein micelles in water, from the fat and protein content.

MILK_DENSITY_G_ML = 1.030
FAT_DENSITY_G_ML = 0.915
CASEIN_DENSITY_G_ML = 1.11
CASEIN_SHARE_OF_PROTEIN = 0.76
FAT_CV = 0.6
CASEIN_MEAN_T = 43.0 / (150.0 - 43.0)
CASEIN_STD_T = 0.23


@dataclass(frozen=True)
class MilkRecipe:
    """Volume fractions and size distributions of milk's particles (FCJ07 sec. 6)."""

    fat_volume_fraction: float
    casein_volume_fraction: float
    fat: LogNormal | None
    casein: LogNormal


def milk_recipe(fat_wt_pct: float, protein_wt_pct: float, homogenization_mpa: float) -> MilkRecipe:
    """FCJ07's milk model: fat and protein weight-% and homogenisation pressure to particles.

    Volume fractions from the weights and densities (fat 0.915, casein 1.11, milk 1.030 g/mL;
    casein is 76 % of the protein). Fat globules: log-normal (by volume) with mean radius
    ``r_vs = r / (cv^2 + 1)``, ``cv = 0.6``, where ``r`` follows FCJ07's fit to homogenisation data,
    ``r = 10^(-a log10 p + b)`` at pressure ``p`` (MPa) and ``r_P0`` unhomogenised; radii
    0.005-10 um. Casein micelles: mean 43 nm, log-normal in ``r / (150 nm - r)`` with standard
    deviation 0.23. The constants are those of FCJ07's implementation (Frisvad 2009).
    """
    for name, value, hi in (
        ("fat_wt_pct", fat_wt_pct, 40.0),
        ("protein_wt_pct", protein_wt_pct, 20.0),
        ("homogenization_mpa", homogenization_mpa, 50.0),
    ):
        if not (math.isfinite(value) and 0.0 <= value <= hi):
            raise ValueError(f"{name}: expected a value in [0, {hi:g}], got {value!r}")
    fat_volume = (fat_wt_pct / FAT_DENSITY_G_ML) / (100.0 / MILK_DENSITY_G_ML)
    casein_volume = (
        CASEIN_SHARE_OF_PROTEIN * (protein_wt_pct / CASEIN_DENSITY_G_ML) / (100.0 / MILK_DENSITY_G_ML)
    )
    fat = None
    if fat_wt_pct > 0:
        w = fat_wt_pct
        r_p50 = 7.481403922e-4 * w * w + 3.203991829e-2 * w + 0.1162155667
        r_p0 = -0.2528033794 * w * w + 1.418606759 * w if w < 2.0 else 1.456189142 * w**0.36
        beta = math.log10(r_p0)
        alpha = beta / math.log10(50.0) - math.log10(r_p50) / math.log10(50.0)
        r = 10.0 ** (-alpha * math.log10(homogenization_mpa) + beta) if homogenization_mpa > 0 else r_p0
        r_vs = r / (FAT_CV**2 + 1.0)
        fat = LogNormal.from_mean_std(r_vs, r_vs * FAT_CV, weighting="volume", range_um=(0.005, 10.0))
    casein = LogNormal.from_mean_std(
        CASEIN_MEAN_T, CASEIN_STD_T, weighting="volume", bound_um=0.150, range_um=(0.0005, 0.1495)
    )
    return MilkRecipe(fat_volume, casein_volume, fat, casein)
