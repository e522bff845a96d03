"""Field types shared by the request bodies and the job parameters (mm)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

__all__ = ["MAX_COORDINATE_MM", "Coordinate", "Point3"]

#: Largest coordinate a request may carry (mm): 10 km, beyond any machine's site, small
#: enough that squares and sums of coordinates stay finite.
MAX_COORDINATE_MM = 1e7

Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE_MM, le=MAX_COORDINATE_MM)]
Point3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3,
                                           description="[x, y, z] mm")]
