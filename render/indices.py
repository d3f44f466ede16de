"""Refractive indices as functions of wavelength: dispersion formulas and tables, with ranges.

Every model knows the wavelength range of the data it came from and refuses to extrapolate:
asking outside it raises a ``ValueError`` that names the model and the range. Indices are
returned as ``n - i kappa`` (``kappa >= 0`` absorbs), the convention of :mod:`render.mie`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _check_range(name: str, range_nm: tuple[float, float], wavelength_nm: np.ndarray) -> None:
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    if not np.all(np.isfinite(lam)) or np.any(lam <= 0):
        raise ValueError("wavelength_nm: expected positive, finite wavelengths in nanometres")
    lo, hi = range_nm
    # A hair of tolerance so that grid ends computed in floating point still count as inside.
    if lam.size and (lam.min() < lo * (1 - 1e-9) or lam.max() > hi * (1 + 1e-9)):
        raise ValueError(
            f"{name}: wavelength {lam.min() if lam.min() < lo else lam.max():g} nm is outside the data's "
            f"range [{lo:g}, {hi:g}] nm"
        )


@dataclass(frozen=True)
class Dispersion:
    """``n^2 = A + sum_i B_i l^2 / (l^2 - C_i) + sum_j D_j / (l^2 - E_j)``, ``l`` in micrometres.

    The Sellmeier form (``A = 1``, ``B``, ``C``) and Devore's form for rutile
    (``n^2 = A + D / (l^2 - E)``, Devore 1951, JOSA 41, 416) are both special cases.
    ``kappa`` is a constant extinction index (0 for the clear dielectrics such formulas fit).
    """

    name: str
    range_nm: tuple[float, float]
    A: float = 1.0
    B: tuple[float, ...] = ()
    C_um2: tuple[float, ...] = ()
    D_um2: tuple[float, ...] = ()
    E_um2: tuple[float, ...] = ()
    kappa: float = 0.0

    def __call__(self, wavelength_nm: np.ndarray | float) -> np.ndarray:
        _check_range(self.name, self.range_nm, np.asarray(wavelength_nm))
        l2 = (np.asarray(wavelength_nm, dtype=np.float64) * 1e-3) ** 2
        n2 = np.full_like(l2, self.A)
        for b, c in zip(self.B, self.C_um2, strict=True):
            n2 = n2 + b * l2 / (l2 - c)
        for d, e in zip(self.D_um2, self.E_um2, strict=True):
            n2 = n2 + d / (l2 - e)
        return np.sqrt(n2) - 1j * self.kappa


@dataclass(frozen=True)
class Table:
    """Tabulated ``n`` and ``kappa``, linearly interpolated between the samples."""

    name: str
    wavelength_nm: tuple[float, ...]
    n: tuple[float, ...]
    kappa: tuple[float, ...]

    def __post_init__(self) -> None:
        lam = np.asarray(self.wavelength_nm)
        if not (lam.size == len(self.n) == len(self.kappa)) or lam.size < 2:
            raise ValueError(f"{self.name}: expected equally long wavelength, n and kappa lists (at least 2)")
        if np.any(np.diff(lam) <= 0):
            raise ValueError(f"{self.name}: expected increasing wavelengths")
        if np.any(np.asarray(self.kappa) < 0) or np.any(np.asarray(self.n) <= 0):
            raise ValueError(f"{self.name}: expected n > 0 and kappa >= 0")

    @property
    def range_nm(self) -> tuple[float, float]:
        return float(self.wavelength_nm[0]), float(self.wavelength_nm[-1])

    def __call__(self, wavelength_nm: np.ndarray | float) -> np.ndarray:
        _check_range(self.name, self.range_nm, np.asarray(wavelength_nm))
        lam = np.asarray(wavelength_nm, dtype=np.float64)
        n = np.interp(lam, self.wavelength_nm, self.n)
        k = np.interp(lam, self.wavelength_nm, self.kappa)
        return n - 1j * k


@dataclass(frozen=True)
class Constant:
    """A constant index over a stated range (e.g. a value measured at one or a few wavelengths)."""

    name: str
    n: float
    range_nm: tuple[float, float]
    kappa: float = 0.0

    def __call__(self, wavelength_nm: np.ndarray | float) -> np.ndarray:
        _check_range(self.name, self.range_nm, np.asarray(wavelength_nm))
        return np.full(np.shape(wavelength_nm), self.n - 1j * self.kappa, dtype=np.complex128)


@dataclass(frozen=True)
class Mean:
    """Weighted mean of other indices, e.g. rutile's ``(2 n_o + n_e) / 3`` for randomly oriented
    crystals (the usual orientation average for birefringent pigment particles)."""

    name: str
    parts: tuple[object, ...]
    weights: tuple[float, ...]

    @property
    def range_nm(self) -> tuple[float, float]:
        ranges = [p.range_nm for p in self.parts]  # type: ignore[attr-defined]
        return max(r[0] for r in ranges), min(r[1] for r in ranges)

    def __call__(self, wavelength_nm: np.ndarray | float) -> np.ndarray:
        _check_range(self.name, self.range_nm, np.asarray(wavelength_nm))
        total = sum(self.weights)
        return sum(w * p(wavelength_nm) for p, w in zip(self.parts, self.weights, strict=True)) / total  # type: ignore[operator]


@dataclass(frozen=True)
class WithAbsorber:
    """A host index plus a dissolved absorber: ``kappa += ln(10) eps(l) c l / (4 pi)``.

    ``eps`` is the decadic molar absorption coefficient (M^-1 cm^-1, tabulated) and ``c`` the
    molar concentration (mol/L); ``sigma_a = 4 pi kappa / l`` (the talk's absorption
    coefficient) then grows by ``ln(10) eps c`` (Beer–Lambert), as FCJ07 add vitamin B2 to milk.
    """

    name: str
    host: object
    absorber_wavelength_nm: tuple[float, ...]
    molar_absorption_l_per_mol_cm: tuple[float, ...]
    concentration_mol_per_l: float

    @property
    def range_nm(self) -> tuple[float, float]:
        lo, hi = self.host.range_nm  # type: ignore[attr-defined]
        return max(lo, self.absorber_wavelength_nm[0]), min(hi, self.absorber_wavelength_nm[-1])

    def __call__(self, wavelength_nm: np.ndarray | float) -> np.ndarray:
        _check_range(self.name, self.range_nm, np.asarray(wavelength_nm))
        lam = np.asarray(wavelength_nm, dtype=np.float64)
        eps = np.interp(lam, self.absorber_wavelength_nm, self.molar_absorption_l_per_mol_cm)
        # (L/mol/cm) * (mol/L) = 1/cm; times 100 for 1/m.
        sigma_per_m = np.log(10.0) * eps * 100.0 * self.concentration_mol_per_l
        kappa = sigma_per_m * lam * 1e-9 / (4.0 * np.pi)
        return self.host(lam) - 1j * kappa  # type: ignore[operator]
