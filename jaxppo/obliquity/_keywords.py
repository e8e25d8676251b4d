"""The scan-setting keywords of ``jaxppo.scan`` and
``jaxppo.marginal_scan``. With a System they build the config (checked by
``check_scan_settings``); a ``ScanConfig`` carries its own settings,
so one given with it is refused rather than silently ignored (issue 24: 360
alphas were scanned for 36 asked)."""

from __future__ import annotations

import numpy as np

__all__ = ["Default", "refuse_with_config", "resolved"]

_ATTR = {"alpha": "alpha", "cases": "cases", "margin": "margin", "detrend": "detrend", "baseline": "baseline",
         "clip": "clip", "multi_transits": "events", "block": "block"}


class Default:
    """An omitted keyword: shown as its default value (``help(jp.scan)``),
    and told apart from the same value given on purpose."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value

    def __repr__(self) -> str:
        return repr(self.value)


def resolved(kw: dict) -> dict:
    """The keywords with every omitted one replaced by its default value."""
    return {k: v.value if isinstance(v, Default) else v for k, v in kw.items()}


def _show(name: str, v) -> str:
    if name == "alpha" and np.ndim(v) == 1 and np.size(v) > 4:
        a = np.asarray(v, float)
        return f"{a.size} alphas, {a[0]:g} to {a[-1]:g} deg"
    return repr(v)


def refuse_with_config(kw: dict, cfg, where: str) -> None:
    """ValueError when a scan setting was given along with the ScanConfig
    ``cfg``: naming each, the config's own value and where to set it."""
    given = [k for k, v in kw.items() if not isinstance(v, Default)]
    if not given:
        return
    each = "; ".join(f"{k} = {_show(k, kw[k])} (the config has {_show(k, getattr(cfg, _ATTR[k]))})" for k in given)
    how = [f"[scan] {k}" for k in given if k != "alpha"]
    hint = ("set " + ", ".join(how) + f" in the config file ({cfg.source})") if how else ""
    if "alpha" in given:
        hint += ("; " if hint else "") + "give the alpha grid as jp.load_config(path, alpha=[start, stop, step])"
    raise ValueError(f"{where}: {', '.join(given)} must not be given with a ScanConfig, which carries its own "
                     f"scan settings: {each}. To change them, {hint}; or pass a System and a LightCurve instead "
                     "of the config")
