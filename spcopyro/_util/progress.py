"""Progress bars for long runs (tqdm), on unless switched off or under CI."""

from __future__ import annotations

import os


def progress_enabled(progress: bool | None) -> bool:
    """Progress bars are on unless switched off, or when running under CI (``$CI`` set)."""
    if progress is None:
        return not os.environ.get("CI")
    return progress
