"""The root of qpik's errors and the ones the core raises (no MuJoCo or mink import here;
:mod:`qpik.errors` re-exports them with the rest)."""

from __future__ import annotations


class QpikError(Exception):
    """Root of all qpik errors."""


class MissingExtra(QpikError, ImportError):
    """An optional dependency is needed: the message names the pip extra."""

    def __init__(self, feature: str, extra: str, package: str):
        self.feature = feature
        self.extra = extra
        self.package = package
        super().__init__(
            f"{feature} needs the package {package!r}: install it with pip install 'qpik[{extra}]'"
        )


class InvalidInput(QpikError, ValueError):
    """An argument of the wrong type, shape or range, or with NaN / inf entries; the
    message names it."""
