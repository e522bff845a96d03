"""Small number helpers shared by every layer (the bottom layer, so all may import it)."""

from __future__ import annotations

import math

__all__ = ["finite_or_none"]


def finite_or_none(x: float) -> float | None:
    """``x`` as a float, or None when it is NaN or infinite (JSON has no such numbers)."""
    return float(x) if math.isfinite(x) else None
