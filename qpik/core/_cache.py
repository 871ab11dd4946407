"""Keep numba's on-disk cache honest across modules.

numba invalidates a cached kernel when *its own* source file changes, not when a kernel it
calls from another module does: the caller's cached machine code still holds the old
callee. :func:`drop_stale_cache` is called by a kernel module at import, before any of its
kernels load; it stores a digest of the modules it depends on beside numba's cache files
and removes that module's cache files when the digest no longer matches (the kernels then
compile once more, 10-60 s).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path

__all__ = ["drop_stale_cache"]


def _cache_dir(module_file: Path) -> Path:
    override = os.environ.get("NUMBA_CACHE_DIR")
    if override:
        # numba mirrors the module's absolute path under the cache directory.
        return Path(override) / module_file.parent.resolve().relative_to("/")
    return module_file.parent / "__pycache__"


def drop_stale_cache(module_file: str, dependencies: Sequence[str]) -> bool:
    """Remove ``module_file``'s numba cache files when a dependency's source changed since
    they were written. Returns True when files were removed. Never raises: a read-only
    install (no cache written either) is left alone."""
    module = Path(module_file)
    try:
        digest = hashlib.sha256()
        for dependency in dependencies:
            digest.update(Path(dependency).read_bytes())
        stamp = digest.hexdigest()
        folder = _cache_dir(module)
        marker = folder / f"{module.stem}.qpik-deps"
        if marker.exists() and marker.read_text() == stamp:
            return False
        removed = False
        if folder.is_dir():
            for path in folder.glob(f"{module.stem}.*"):
                if path.suffix in (".nbi", ".nbc"):
                    path.unlink()
                    removed = True
        folder.mkdir(parents=True, exist_ok=True)
        marker.write_text(stamp)
        return removed
    except OSError:
        return False
