"""PHOENIX model atmospheres: SPECINT reader, passband integration, and the
bundled limb-darkening grids (Claret 2018; Claret & Southworth 2023;
Espinoza & Jordan 2015). Provenance: jaxppo/data/README.md.
"""

from __future__ import annotations

import dataclasses
from importlib import resources
from pathlib import Path

import numpy as np

from ._star import Star

__all__ = [
    "PhoenixIntensities",
    "read_specint",
    "kepler_response",
    "band_intensity",
    "truncate_limb",
    "phoenix_star",
    "claret_quadratic",
    "claret_power2",
    "kepler20_star",
    "data_path",
]


def data_path(name: str) -> Path:
    """Path of a file bundled in jaxppo/data."""
    return Path(str(resources.files("jaxppo") / "data" / name))


@dataclasses.dataclass(frozen=True)
class PhoenixIntensities:
    """Specific intensities of one model: ``intensity[mu, wavelength]``.

    ``mu`` ascending in (0, 1]; ``wavelength`` [Angstrom] ascending.
    """

    mu: np.ndarray
    wavelength: np.ndarray
    intensity: np.ndarray
    header: dict


def read_specint(path: str | Path) -> PhoenixIntensities:
    """Read a Husser et al. (2013) PHOENIX-ACES SPECINT FITS file.

    Layout (lte*-PHOENIX-ACES-AGSS-COND-SPECINT-2011.fits): the primary HDU
    holds I(mu, lambda) with shape (n_mu, n_lambda); the wavelength axis is the
    linear WCS of axis 1 (CRVAL1, CDELT1, CRPIX1; Angstrom unless CUNIT1 says
    otherwise); the mu values are the data of the extension named ``MU`` (or the
    first extension). The file's own axes are used; nothing is assumed.

    Raises:
        ValueError: the file lacks the intensity array, the WCS keywords, or the
            mu axis, or their sizes disagree.
    """
    from astropy.io import fits

    path = Path(path)
    if not path.exists():
        raise ValueError(f"PHOENIX file not found: {path}")
    with fits.open(path) as hdul:
        data = hdul[0].data
        hdr = hdul[0].header
        if data is None or np.ndim(data) != 2:
            raise ValueError(f"{path}: primary HDU must hold a 2D intensity array (mu, wavelength), got {None if data is None else np.shape(data)}")
        missing = [k for k in ("CRVAL1", "CDELT1") if k not in hdr]
        if missing:
            raise ValueError(f"{path}: primary header lacks the wavelength axis keywords {missing}")
        mu_hdu = None
        for hdu in hdul[1:]:
            if hdu.name.upper() == "MU":
                mu_hdu = hdu
                break
        if mu_hdu is None and len(hdul) > 1:
            mu_hdu = hdul[1]
        if mu_hdu is None or mu_hdu.data is None:
            raise ValueError(f"{path}: no mu axis (expected an extension named 'MU')")
        mu_data = mu_hdu.data
        if getattr(mu_data, "dtype", None) is not None and mu_data.dtype.names:
            mu_data = mu_data[mu_data.dtype.names[0]]
        mu = np.asarray(mu_data, dtype=float).ravel()
        inten = np.asarray(data, dtype=float)
        n_wave = inten.shape[1]
        crpix = float(hdr.get("CRPIX1", 1.0))
        wave = float(hdr["CRVAL1"]) + (np.arange(n_wave) + 1 - crpix) * float(hdr["CDELT1"])
        unit = str(hdr.get("CUNIT1", "Angstrom")).strip().lower()
        if unit in ("nm", "nanometer", "nanometers"):
            wave = wave * 10.0
        elif unit in ("um", "micron", "microns", "micrometer"):
            wave = wave * 1e4
        if mu.size != inten.shape[0]:
            raise ValueError(f"{path}: {mu.size} mu values for {inten.shape[0]} intensity rows")
        header = {k: hdr[k] for k in ("PHXTEFF", "PHXLOGG", "PHXM_H", "PHXALPHA") if k in hdr}
    order = np.argsort(mu)
    return PhoenixIntensities(mu=mu[order], wavelength=wave, intensity=inten[order], header=header)


def kepler_response() -> tuple[np.ndarray, np.ndarray]:
    """Kepler response function (Van Cleve 2009): wavelength [Angstrom], response."""
    table = np.loadtxt(data_path("kepler_response_hires1.txt"), comments="#")
    return table[:, 0] * 10.0, table[:, 1]


def band_intensity(model: PhoenixIntensities, response=None, photon: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Passband-integrated I(mu) = int I_lambda(mu) R(lambda) [lambda] dlambda.

    ``response``: (wavelength [Angstrom], R) (default Kepler); ``photon``
    weights by lambda (photon-counting detectors). Trapezoidal rule on the
    model's wavelength grid with R interpolated onto it (zero outside).
    """
    wave_r, resp = kepler_response() if response is None else response
    r = np.interp(model.wavelength, wave_r, resp, left=0.0, right=0.0)
    weight = r * (model.wavelength if photon else 1.0)
    if not np.any(weight > 0):
        raise ValueError("the passband does not overlap the model's wavelength range")
    trapezoid = getattr(np, "trapezoid", None) or np.trapz
    band = trapezoid(model.intensity * weight[None, :], model.wavelength, axis=1)
    return model.mu, band


def truncate_limb(mu: np.ndarray, inten: np.ndarray, method: str = "rescale") -> tuple[np.ndarray, np.ndarray, float]:
    """Treat the limb of a spherical model.

    PHOENIX spherical models extend past the photosphere: I drops steeply near
    mu_cri. With ``"rescale"`` (default; the point of steepest drop,
    max |dI/dr|, as in Claret & Southworth 2023 method M1) the star's radius is
    put at r_cri, radii are rescaled r' = r / r_cri, points outside are
    dropped and mu' = sqrt(1 - r'^2). ``"cut"`` sets I = 0 for mu < mu_cri
    without rescaling; ``"none"`` returns the table unchanged.

    Returns (mu', I', mu_cri).
    """
    mu = np.asarray(mu, float)
    inten = np.asarray(inten, float)
    if method == "none":
        return mu, inten, 0.0
    r = np.sqrt(np.clip(1.0 - mu**2, 0.0, 1.0))
    # dI/dr between neighbouring points (mu ascending -> r descending); the
    # steepest drop lies between node k (outside) and node k + 1 (the last
    # photospheric point, which becomes the new limb).
    slope = np.abs(np.diff(inten) / np.diff(r))
    k = int(np.argmax(slope))
    mu_cri = float(mu[k + 1])
    r_cri = np.sqrt(1.0 - mu_cri**2)
    if method == "cut":
        out = np.where(mu >= mu_cri, inten, 0.0)
        return mu, out, mu_cri
    if method != "rescale":
        raise ValueError(f"limb method must be 'rescale', 'cut' or 'none', got {method!r}")
    keep = mu >= mu_cri
    r_new = r[keep] / r_cri
    mu_new = np.sqrt(np.clip(1.0 - r_new**2, 0.0, 1.0))
    i_new = inten[keep]
    mu_new[0] = 0.0
    return mu_new, i_new, mu_cri


def phoenix_star(path: str | Path, response=None, limb: str = "rescale", interpolation: str = "sqrt-poly") -> Star:
    """A tabulated Star from a PHOENIX SPECINT file: passband-integrated
    (Kepler by default, photon-weighted), limb treated by ``truncate_limb``,
    normalised to I(mu = 1) = 1. A file whose mu grid stops short of 0 gets a
    node at mu = 0: I = 0 with ``limb="cut"`` (the cut limb is dark), the
    outermost intensity with ``limb="none"`` (``"rescale"`` ends at mu = 0)."""
    model = read_specint(path)
    mu, band = band_intensity(model, response)
    mu, band, _ = truncate_limb(mu, band, limb)
    if mu[0] > 0.0:
        band = np.concatenate([[0.0 if limb == "cut" else band[0]], band])
        mu = np.concatenate([[0.0], mu])
    if mu[-1] < 1.0:
        band = np.concatenate([band, [band[-1]]])
        mu = np.concatenate([mu, [1.0]])
    return Star.tabulated(mu, band / band[-1], interpolation=interpolation)


def _grid(name: str, cols: tuple[int, ...]) -> np.ndarray:
    rows = []
    with open(data_path(name)) as fh:
        for line in fh:
            parts = line.split()
            if len(parts) < max(cols) + 1:
                continue
            try:
                rows.append([float(parts[c]) for c in cols])
            except ValueError:
                continue
    return np.asarray(rows)


def _bilinear(table: np.ndarray, teff: float, logg: float, what: str) -> np.ndarray:
    """Bilinear interpolation in (Teff, log g) on a regular grid of rows
    (logg, teff, values...); raises outside the grid."""
    if not (np.isfinite(teff) and np.isfinite(logg)):
        raise ValueError(f"teff and logg must be finite, got {teff}, {logg}")
    tg = np.unique(table[:, 1])
    gg = np.unique(table[:, 0])
    if not (tg[0] <= teff <= tg[-1]):
        raise ValueError(f"teff={teff} K is outside the {what} grid [{tg[0]}, {tg[-1]}] K")
    if not (gg[0] <= logg <= gg[-1]):
        raise ValueError(f"logg={logg} is outside the {what} grid [{gg[0]}, {gg[-1]}]")
    i = int(np.clip(np.searchsorted(tg, teff) - 1, 0, len(tg) - 2))
    j = int(np.clip(np.searchsorted(gg, logg) - 1, 0, len(gg) - 2))
    ft = (teff - tg[i]) / (tg[i + 1] - tg[i])
    fg = (logg - gg[j]) / (gg[j + 1] - gg[j])
    out = 0.0
    for ti, wt in ((tg[i], 1 - ft), (tg[i + 1], ft)):
        for gj, wg in ((gg[j], 1 - fg), (gg[j + 1], fg)):
            sel = (table[:, 1] == ti) & (table[:, 0] == gj)
            if not np.any(sel):
                raise ValueError(f"the {what} grid has no model at Teff={ti}, logg={gj}")
            out = out + wt * wg * table[sel][0, 2:]
    return out


def claret_quadratic(teff: float, logg: float, model: str = "cond") -> Star:
    """Quadratic-law star from Claret (2018) PHOENIX spherical fits, Kepler band,
    solar metallicity, bilinear in (Teff, log g)."""
    names = {"cond": "claret2018_quad_phoenix_cond_kepler.dat", "drift": "claret2018_quad_phoenix_drift_kepler.dat"}
    if model not in names:
        raise ValueError(f"model must be 'cond' or 'drift', got {model!r}")
    u1, u2 = _bilinear(_grid(names[model], (0, 1, 4, 5)), teff, logg, f"Claret 2018 PHOENIX-{model.upper()}")
    return Star.quadratic(float(u1), float(u2))


_P2_BANDS = ("Gbp", "G", "Grp", "Kepler", "TESS", "CHEOPS")


def claret_power2(teff: float, logg: float, band: str = "Kepler", method: str = "M1") -> Star:
    """Power-2 star (c = g, alpha = h) from Claret & Southworth (2023), PHOENIX-COND."""
    if band not in _P2_BANDS:
        raise ValueError(f"band must be one of {_P2_BANDS}, got {band!r}")
    files = {"M1": "claret2023_power2_phoenix_m1.dat", "M2": "claret2023_power2_phoenix_m2.dat"}
    if method not in files:
        raise ValueError(f"method must be 'M1' or 'M2', got {method!r}")
    b = _P2_BANDS.index(band)
    g, h = _bilinear(_grid(files[method], (0, 1, 4 + b, 10 + b)), teff, logg, "Claret & Southworth 2023")
    return Star.power2(float(g), float(h))


def kepler20_star() -> Star:
    """The default Kepler-20-like star: non-linear law fitted to PHOENIX-ACES
    specific intensities (Teff 5500 K, log g 4.5, [M/H] 0; Espinoza & Jordan
    2015, row P100, Kepler high-resolution response)."""
    with open(data_path("espinoza2015_ldc_phoenix_kepler_5500.dat")) as fh:
        for line in fh:
            parts = line.split()
            if len(parts) > 16 and parts[1] == "P100":
                c = [float(v) for v in parts[13:17]]
                return Star.nonlinear(*c)
    raise ValueError("P100 row missing from the bundled Espinoza & Jordan table")
