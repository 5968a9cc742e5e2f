"""Output files written atomically.

Every file the tool writes (results CSV, figures) is first written under a temporary name in the
same folder and then renamed over the target with :func:`os.replace`, so an interrupted or failed
write never leaves a shorter file that looks complete, and an existing file is kept until the new
one is whole.
"""
from __future__ import annotations

import os
import secrets
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_output(path):
    """Yield a temporary path next to ``path`` (same suffix, so writers that pick the format from
    the suffix still work); on success it replaces ``path``, on any exception it is removed."""
    target = Path(path)
    tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}.part{target.suffix}")
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
