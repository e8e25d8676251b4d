"""Read-only dict access to a result's ``summary``, kept until 1.0.

``jaxppo.ScanResult`` and ``jaxppo.MarginalResult`` used to be
dict subclasses (the summary itself). They are frozen dataclasses now, with
the summary in their ``summary`` field; ``result["key"]``, ``result.get``,
``key in result``, ``keys()``, ``items()`` and ``values()`` still read it but
warn (DeprecationWarning) and go away in 1.0."""

from __future__ import annotations

import warnings

__all__ = ["DeprecatedSummaryAccess"]


class DeprecatedSummaryAccess:
    """Mixin: the deprecated dict reads of ``self.summary``."""

    summary: dict

    def _warn(self, what: str) -> None:
        warnings.warn(f"{type(self).__name__}{what} is deprecated and will be removed in 1.0; "
                      f"read result.summary{what} (or an attribute) instead", DeprecationWarning, stacklevel=3)

    def __getitem__(self, key):
        self._warn(f"[{key!r}]")
        return self.summary[key]

    def get(self, key, default=None):
        """Deprecated: ``result.summary.get(key, default)``, with a DeprecationWarning.

        Parameters
        ----------
        key : str
            A key of ``summary``.
        default : object, optional
            Returned when ``key`` is missing.

        Returns
        -------
        object
            ``summary[key]``, or ``default``.
        """
        self._warn(f".get({key!r})")
        return self.summary.get(key, default)

    def __contains__(self, key) -> bool:
        self._warn(".__contains__")
        return key in self.summary

    def __iter__(self):
        self._warn(".__iter__")
        return iter(self.summary)

    def keys(self):
        """Deprecated: ``result.summary.keys()``, with a DeprecationWarning."""
        self._warn(".keys()")
        return self.summary.keys()

    def items(self):
        """Deprecated: ``result.summary.items()``, with a DeprecationWarning."""
        self._warn(".items()")
        return self.summary.items()

    def values(self):
        """Deprecated: ``result.summary.values()``, with a DeprecationWarning."""
        self._warn(".values()")
        return self.summary.values()
