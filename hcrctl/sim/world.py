"""The simulator's room: walls, obstacles, ray casting and contact tests.

Pure geometry, standard library only, so the robot model can ask "how far is
the nearest thing along this ray" and "would a circle here overlap anything"
without knowing what the room looks like.

Coordinates are centimetres with x to the east and y to the north; headings
are compass degrees (0 = north, 90 = east, clockwise positive), so a heading
``h`` points along ``(sin h, cos h)``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

ROOM_WIDTH_CM = 300.0
ROOM_HEIGHT_CM = 200.0


@dataclass(frozen=True)
class Box:
    """An axis-aligned rectangular obstacle."""

    x0: float
    y0: float
    x1: float
    y1: float

    def nearest(self, x: float, y: float) -> tuple[float, float]:
        return min(max(x, self.x0), self.x1), min(max(y, self.y0), self.y1)

    def contains(self, x: float, y: float) -> bool:
        return self.x0 <= x <= self.x1 and self.y0 <= y <= self.y1

    def ray(self, x: float, y: float, dx: float, dy: float) -> float | None:
        """Slab method: the distance at which the ray enters the box."""
        near, far = 0.0, math.inf
        for p, d, lo, hi in ((x, dx, self.x0, self.x1), (y, dy, self.y0, self.y1)):
            if abs(d) < 1e-12:
                if not lo <= p <= hi:
                    return None
                continue
            t0, t1 = sorted(((lo - p) / d, (hi - p) / d))
            near, far = max(near, t0), min(far, t1)
        return near if near <= far else None


@dataclass(frozen=True)
class Circle:
    """A round obstacle (a bin, a table leg)."""

    cx: float
    cy: float
    r: float

    def nearest(self, x: float, y: float) -> tuple[float, float]:
        dist = math.hypot(x - self.cx, y - self.cy) or 1.0
        return self.cx + (x - self.cx) * self.r / dist, self.cy + (y - self.cy) * self.r / dist

    def contains(self, x: float, y: float) -> bool:
        return math.hypot(x - self.cx, y - self.cy) <= self.r

    def ray(self, x: float, y: float, dx: float, dy: float) -> float | None:
        ox, oy = x - self.cx, y - self.cy
        b = ox * dx + oy * dy
        c = ox * ox + oy * oy - self.r * self.r
        disc = b * b - c
        if disc < 0:
            return None
        if c <= 0:
            return 0.0
        t = -b - math.sqrt(disc)
        return t if t >= 0 else None


Obstacle = Box | Circle

#: A table in the north-east and a bin in the south: both clear of the
#: straight line the robot faces from its start pose, so "drive forward" reaches a wall.
OBSTACLES: tuple[Obstacle, ...] = (Box(200.0, 130.0, 240.0, 170.0), Circle(150.0, 45.0, 15.0))


@dataclass(frozen=True)
class World:
    width: float = ROOM_WIDTH_CM
    height: float = ROOM_HEIGHT_CM
    obstacles: tuple[Obstacle, ...] = OBSTACLES

    def ray(self, x: float, y: float, heading: float) -> float:
        """Distance from (x, y) to the first wall or obstacle along ``heading``."""
        dx, dy = math.sin(math.radians(heading)), math.cos(math.radians(heading))
        best = self._wall_ray(x, y, dx, dy)
        for ob in self.obstacles:
            t = ob.ray(x, y, dx, dy)
            if t is not None and t < best:
                best = t
        return best

    def _wall_ray(self, x: float, y: float, dx: float, dy: float) -> float:
        best = math.inf
        for p, d, size in ((x, dx, self.width), (y, dy, self.height)):
            if d > 1e-12:
                best = min(best, (size - p) / d)
            elif d < -1e-12:
                best = min(best, -p / d)
        return max(best, 0.0)

    def blocked(self, x: float, y: float, r: float) -> bool:
        """Whether a circle of radius ``r`` at (x, y) overlaps a wall or an obstacle."""
        if not (r <= x <= self.width - r and r <= y <= self.height - r):
            return True
        return any(math.hypot(x - px, y - py) < r - 1e-9 for px, py in self._obstacle_points(x, y))

    def occupied(self, x: float, y: float) -> bool:
        """Whether the point is outside the room or inside an obstacle."""
        inside = 0 <= x <= self.width and 0 <= y <= self.height
        return not inside or any(ob.contains(x, y) for ob in self.obstacles)

    def contacts(self, x: float, y: float, reach: float) -> Iterator[float]:
        """Compass bearings from (x, y) of every surface point within ``reach``."""
        for px, py in self._surface_points(x, y):
            if math.hypot(px - x, py - y) <= reach:
                yield math.degrees(math.atan2(px - x, py - y)) % 360

    def _surface_points(self, x: float, y: float) -> Iterator[tuple[float, float]]:
        yield from ((0.0, y), (self.width, y), (x, 0.0), (x, self.height))
        yield from self._obstacle_points(x, y)

    def _obstacle_points(self, x: float, y: float) -> Iterator[tuple[float, float]]:
        return (ob.nearest(x, y) for ob in self.obstacles)
