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
    otherwise: nm and um are converted); the mu values are the data of the
    extension named ``MU`` (or the first extension). The file's own axes are
    used; nothing is assumed. Needs astropy.

    Parameters
    ----------
    path : str or pathlib.Path
        The SPECINT FITS file.

    Returns
    -------
    model : PhoenixIntensities
        A frozen dataclass with ``mu`` [n_mu] (sorted ascending, in (0, 1]),
        ``wavelength`` [Angstrom], shape [n_lambda] (ascending), ``intensity``
        [n_mu, n_lambda] (the file's specific intensities, rows in the order
        of ``mu``) and ``header`` (a dict of the model's PHXTEFF, PHXLOGG,
        PHXM_H and PHXALPHA, those the file has).

    Raises
    ------
    ValueError
        When the file does not exist, its primary HDU holds no 2D intensity
        array, the primary header lacks CRVAL1 or CDELT1, there is no mu axis
        (no extension, or one without data), or the number of mu values
        differs from the number of intensity rows.

    See Also
    --------
    band_intensity : integrate the intensities over a passband.
    phoenix_star : a ``Star`` straight from such a file.

    Examples
    --------
    A small synthetic file of the same layout (a real one is a download from
    the PHOENIX library):

    >>> import numpy as np
    >>> from astropy.io import fits
    >>> import jaxppo as jp
    >>> mu = np.concatenate([[0.01, 0.03], np.linspace(0.05, 1.0, 20)])
    >>> limb = np.where(mu < 0.05, 0.02, 1.0 - 0.6 * (1.0 - mu))  # a faint atmosphere outside mu = 0.05
    >>> hdu = fits.PrimaryHDU(np.outer(limb, np.ones(800)))  # I[mu, wavelength], a flat spectrum
    >>> hdu.header.update(CRVAL1=3000.0, CDELT1=10.0)  # wavelength = 3000 + 10 k [Angstrom]
    >>> fits.HDUList([hdu, fits.ImageHDU(mu, name="MU")]).writeto("specint.fits", overwrite=True)
    >>> model = jp.read_specint("specint.fits")
    >>> model.mu.shape, model.intensity.shape
    ((22,), (22, 800))
    >>> print(model.wavelength[0], model.wavelength[-1])
    3000.0 10990.0
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
    """Load the Kepler response function (Van Cleve & Caldwell 2009).

    The bundled high-resolution table (jaxppo/data/kepler_response_hires1.txt,
    348-970 nm in 1 nm steps), the default passband of
    ``band_intensity`` and ``phoenix_star``.

    Returns
    -------
    wavelength : numpy.ndarray
        Wavelengths [Angstrom], ascending, [n_lambda].
    response : numpy.ndarray
        Transmission at each wavelength (dimensionless, peak ~0.73), [n_lambda].

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> wave, resp = jp.kepler_response()
    >>> print(wave[0], wave[-1], wave[np.argmax(resp)])
    3480.0 9700.0 5890.0
    """
    table = np.loadtxt(data_path("kepler_response_hires1.txt"), comments="#")
    return table[:, 0] * 10.0, table[:, 1]


def band_intensity(model: PhoenixIntensities, response=None, photon: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Integrate specific intensities over a passband.

    I(mu) = int I_lambda(mu) R(lambda) [lambda] dlambda, by the trapezoidal
    rule on the model's wavelength grid with R interpolated onto it (zero
    outside the response table). The factor lambda (``photon=True``) weights
    by photon number, for photon-counting detectors such as Kepler's.

    Parameters
    ----------
    model : PhoenixIntensities
        Specific intensities, as ``read_specint`` returns them.
    response : tuple of two array_like, optional
        ``(wavelength [Angstrom], R)``, the passband's response; default
        (None): Kepler's (``kepler_response``).
    photon : bool, optional
        Weight by lambda (photon counting; default True); False integrates
        energy.

    Returns
    -------
    mu : numpy.ndarray
        The model's mu, ascending, [n_mu].
    intensity : numpy.ndarray
        The band-integrated intensity at each mu, [n_mu] (the model's units
        times those of R and lambda; not normalised).

    Raises
    ------
    ValueError
        When the passband does not overlap the model's wavelength range (the
        weight is zero everywhere on its grid).

    Examples
    --------
    >>> import numpy as np
    >>> from astropy.io import fits
    >>> import jaxppo as jp
    >>> mu = np.concatenate([[0.01, 0.03], np.linspace(0.05, 1.0, 20)])
    >>> limb = np.where(mu < 0.05, 0.02, 1.0 - 0.6 * (1.0 - mu))  # a faint atmosphere outside mu = 0.05
    >>> hdu = fits.PrimaryHDU(np.outer(limb, np.ones(800)))  # I[mu, wavelength], a flat spectrum
    >>> hdu.header.update(CRVAL1=3000.0, CDELT1=10.0)  # wavelength = 3000 + 10 k [Angstrom]
    >>> fits.HDUList([hdu, fits.ImageHDU(mu, name="MU")]).writeto("specint.fits", overwrite=True)
    >>> mu, band = jp.band_intensity(jp.read_specint("specint.fits"))
    >>> print(f"{band[0] / band[-1]:.3f} {band[-2] / band[-1]:.3f}")  # relative to the centre, mu = 1
    0.020 0.970
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
    """Treat the limb of a spherical model atmosphere.

    PHOENIX spherical models extend past the photosphere: I drops steeply near
    mu_cri, the point of steepest drop, max |dI/dr| with r = sqrt(1 - mu^2)
    (as in Claret & Southworth 2023, method M1). With ``"rescale"``
    (default) the star's radius is put at r_cri, radii are rescaled
    r' = r / r_cri, points outside are dropped and mu' = sqrt(1 - r'^2) (the
    new limb is at mu' = 0). ``"cut"`` sets I = 0 for mu < mu_cri without
    rescaling; ``"none"`` returns the table unchanged.

    Parameters
    ----------
    mu : array_like
        mu values, ascending, [n_mu].
    inten : array_like
        Intensity at each mu, [n_mu].
    method : {"rescale", "cut", "none"}, optional
        The treatment (default "rescale").

    Returns
    -------
    mu_new : numpy.ndarray
        mu' ("rescale": [n_kept], starting at 0) or ``mu`` itself.
    inten_new : numpy.ndarray
        The intensities at ``mu_new``.
    mu_cri : float
        mu of the steepest drop, in the original table's mu (0.0 with
        ``"none"``).

    Raises
    ------
    ValueError
        When ``method`` is not "rescale", "cut" or "none".

    Examples
    --------
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> mu = np.array([0.0, 0.02, 0.05, 0.1, 0.3, 0.6, 1.0])
    >>> inten = np.array([0.001, 0.01, 0.4, 0.45, 0.6, 0.8, 1.0])  # a faint atmosphere outside mu = 0.05
    >>> mu_new, i_new, mu_cri = jp.truncate_limb(mu, inten)
    >>> print(mu_cri, np.round(mu_new, 4), i_new)
    0.05 [0.     0.0867 0.2962 0.5987 1.    ] [0.4  0.45 0.6  0.8  1.  ]
    >>> print(jp.truncate_limb(mu, inten, method="cut")[1])
    [0.   0.   0.4  0.45 0.6  0.8  1.  ]
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
    """Build a tabulated ``Star`` from a PHOENIX SPECINT file.

    The file is read by ``read_specint``, integrated over the passband
    (Kepler by default, photon-weighted; ``band_intensity``), its limb
    treated by ``truncate_limb`` and the profile normalised to
    I(mu = 1) = 1, then given to ``Star.tabulated``. A file whose mu grid
    stops short of 0 gets a node at mu = 0: I = 0 with ``limb="cut"`` (the
    cut limb is dark), the outermost intensity with ``limb="none"``
    (``"rescale"`` ends at mu = 0); one short of 1 repeats the innermost
    intensity at mu = 1.

    Parameters
    ----------
    path : str or pathlib.Path
        The SPECINT FITS file (layout in ``read_specint``).
    response : tuple of two array_like, optional
        ``(wavelength [Angstrom], R)``; default (None): the Kepler response.
    limb : {"rescale", "cut", "none"}, optional
        The limb treatment of ``truncate_limb`` (default "rescale").
    interpolation : {"sqrt-poly", "linear", "cubic"}, optional
        The table's interpolation (``Star.tabulated``; default
        "sqrt-poly"). The kink of ``limb="cut"`` is better served by
        "linear" (a sqrt-poly fit smooths it and warns).

    Returns
    -------
    star : Star
        A ``law="tabulated"`` star.

    Raises
    ------
    ValueError
        From ``read_specint`` (a missing or malformed file),
        ``band_intensity`` (a passband off the model's wavelengths),
        ``truncate_limb`` (an unknown ``limb``) or ``Star.tabulated``
        (an unknown ``interpolation``).

    Examples
    --------
    >>> import numpy as np
    >>> from astropy.io import fits
    >>> import jaxppo as jp
    >>> mu = np.concatenate([[0.01, 0.03], np.linspace(0.05, 1.0, 20)])
    >>> limb = np.where(mu < 0.05, 0.02, 1.0 - 0.6 * (1.0 - mu))  # a faint atmosphere outside mu = 0.05
    >>> hdu = fits.PrimaryHDU(np.outer(limb, np.ones(800)))  # I[mu, wavelength], a flat spectrum
    >>> hdu.header.update(CRVAL1=3000.0, CDELT1=10.0)  # wavelength = 3000 + 10 k [Angstrom]
    >>> fits.HDUList([hdu, fits.ImageHDU(mu, name="MU")]).writeto("specint.fits", overwrite=True)
    >>> star = jp.phoenix_star("specint.fits")
    >>> star
    Star.tabulated(20 points, interpolation='sqrt-poly', degree=9, residual=8.52e-07)
    >>> print(f"I(0) = {float(star.intensity(0.0)):.4f}, F0 = {float(star.total_flux):.4f}")
    I(0) = 0.4300, F0 = 2.5163
    """
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
    """Build a quadratic-law star from the Claret (2018) PHOENIX tables.

    Claret (2018, A&A 618, A20) fitted u1, u2 (his a, b) to PHOENIX spherical
    models, Kepler band, solar metallicity; the bundled tables are
    interpolated bilinearly in (Teff, log g).

    Parameters
    ----------
    teff : float
        Effective temperature [K]: 2300-12000 ("cond"), 1500-3000 ("drift").
    logg : float
        Surface gravity log10(g [cm/s^2]): 2.5-6.0 ("cond"), 2.5-5.5
        ("drift").
    model : {"cond", "drift"}, optional
        PHOENIX-COND (default) or PHOENIX-DRIFT (dusty, cool) models.

    Returns
    -------
    star : Star
        ``Star.quadratic(u1, u2)``.

    Raises
    ------
    ValueError
        When ``model`` is not "cond" or "drift", ``teff`` or ``logg`` is not
        finite or lies outside the grid, or the grid lacks a corner model.

    Examples
    --------
    >>> import jaxppo as jp
    >>> jp.claret_quadratic(5500.0, 4.5)
    Star.quadratic(0.5046, 0.1752)
    """
    names = {"cond": "claret2018_quad_phoenix_cond_kepler.dat", "drift": "claret2018_quad_phoenix_drift_kepler.dat"}
    if model not in names:
        raise ValueError(f"model must be 'cond' or 'drift', got {model!r}")
    u1, u2 = _bilinear(_grid(names[model], (0, 1, 4, 5)), teff, logg, f"Claret 2018 PHOENIX-{model.upper()}")
    return Star.quadratic(float(u1), float(u2))


_P2_BANDS = ("Gbp", "G", "Grp", "Kepler", "TESS", "CHEOPS")


def claret_power2(teff: float, logg: float, band: str = "Kepler", method: str = "M1") -> Star:
    """Build a power-2 law star from the Claret & Southworth (2023) tables.

    Claret & Southworth (2023, A&A 674, A63) fitted the power-2 law
    I = 1 - g (1 - mu^h) to PHOENIX-COND intensities; this returns
    ``Star.power2(c=g, alpha=h)``, interpolated bilinearly in (Teff, log g).

    Parameters
    ----------
    teff : float
        Effective temperature [K], 2300-12000.
    logg : float
        Surface gravity log10(g [cm/s^2]), 0.0-6.0.
    band : {"Gbp", "G", "Grp", "Kepler", "TESS", "CHEOPS"}, optional
        Passband (default "Kepler").
    method : {"M1", "M2"}, optional
        The authors' limb truncation method (default "M1", the steepest
        drop, as ``truncate_limb``'s "rescale").

    Returns
    -------
    star : Star
        ``Star.power2(g, h)``.

    Raises
    ------
    ValueError
        When ``band`` or ``method`` is unknown, ``teff`` or ``logg`` is not
        finite or lies outside the grid, or the grid lacks a corner model.

    Examples
    --------
    >>> import jaxppo as jp
    >>> jp.claret_power2(5500.0, 4.5)
    Star.power2(0.717803, 0.776447)
    >>> jp.claret_power2(5500.0, 4.5, band="TESS")
    Star.power2(0.645619, 0.681393)
    """
    if band not in _P2_BANDS:
        raise ValueError(f"band must be one of {_P2_BANDS}, got {band!r}")
    files = {"M1": "claret2023_power2_phoenix_m1.dat", "M2": "claret2023_power2_phoenix_m2.dat"}
    if method not in files:
        raise ValueError(f"method must be 'M1' or 'M2', got {method!r}")
    b = _P2_BANDS.index(band)
    g, h = _bilinear(_grid(files[method], (0, 1, 4 + b, 10 + b)), teff, logg, "Claret & Southworth 2023")
    return Star.power2(float(g), float(h))


def kepler20_star() -> Star:
    """Build the default Kepler-20-like star.

    The non-linear law (Claret 2000) fitted to PHOENIX-ACES specific
    intensities (Teff 5500 K, log g 4.5, [M/H] 0; Espinoza & Jordan 2015,
    row P100, Kepler high-resolution response), read from the bundled table.

    Returns
    -------
    star : Star
        ``Star.nonlinear(c1, c2, c3, c4)``.

    Raises
    ------
    ValueError
        When the bundled table lacks its P100 row (a damaged installation).

    Examples
    --------
    >>> import jaxppo as jp
    >>> star = jp.kepler20_star()
    >>> star
    Star.nonlinear(1.09847, -1.74332, 2.46865, -0.995094)
    >>> print(f"I(limb) / I(centre) = {float(star.intensity(0.0)):.4f}")
    I(limb) / I(centre) = 0.1713
    """
    with open(data_path("espinoza2015_ldc_phoenix_kepler_5500.dat")) as fh:
        for line in fh:
            parts = line.split()
            if len(parts) > 16 and parts[1] == "P100":
                c = [float(v) for v in parts[13:17]]
                return Star.nonlinear(*c)
    raise ValueError("P100 row missing from the bundled Espinoza & Jordan table")
