"""
Latitude/longitude <-> a local east-north-up plane, vectorised (WGS-84).

Exact through Earth-centred Earth-fixed coordinates; in a REP-105 ``odom``/``map`` frame ENU
``(east, north)`` is ``(x, y)``. The simulator writes fixes with it, identification reads them.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ._checks import require_numbers

# WGS-84 ellipsoid.
A = 6378137.0
F = 1.0 / 298.257223563
E2 = F * (2.0 - F)
B = A * (1.0 - F)
EP2 = E2 / (1.0 - E2)


@dataclass(frozen=True, slots=True)
class GeoOrigin:
    """Origin of a local ENU plane: latitude, longitude (degrees), altitude (m above WGS-84)."""

    latitude: float = 0.0
    longitude: float = 0.0
    altitude: float = 0.0

    def __post_init__(self):
        require_numbers(self, finite=('latitude', 'longitude', 'altitude'))
        if abs(self.latitude) > 90.0:
            raise ValueError(f'latitude must be in [-90, 90] degrees, got {self.latitude!r}')


def _ecef(lat_deg, lon_deg, alt):
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    sin_lat = np.sin(lat)
    n = A / np.sqrt(1.0 - E2 * sin_lat * sin_lat)
    return ((n + alt) * np.cos(lat) * np.cos(lon), (n + alt) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - E2) + alt) * sin_lat)


def _rotation(origin: GeoOrigin):
    """Rows: the east, north and up unit vectors of the origin, in ECEF."""
    lat, lon = math.radians(origin.latitude), math.radians(origin.longitude)
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def geodetic_to_enu(latitude, longitude, altitude, origin: GeoOrigin):
    """
    East, north, up (m) of geodetic positions (degrees, m) in the tangent plane at ``origin``.

    A NaN altitude is taken as the origin's.
    """
    lat = np.asarray(latitude, dtype=float)
    lon = np.asarray(longitude, dtype=float)
    alt = np.broadcast_to(np.asarray(altitude, dtype=float), lat.shape)
    alt = np.where(np.isfinite(alt), alt, origin.altitude)
    p = np.stack(_ecef(lat, lon, alt), axis=-1)
    p0 = np.array(_ecef(origin.latitude, origin.longitude, origin.altitude))
    enu = (p - p0) @ _rotation(origin).T
    return enu[..., 0], enu[..., 1], enu[..., 2]


def enu_to_geodetic(east, north, up, origin: GeoOrigin):
    """
    Latitude, longitude (degrees) and altitude (m) of points (m) in the plane at ``origin``.

    The inverse of :func:`geodetic_to_enu`; Bowring's latitude with one Newton refinement.
    """
    enu = np.stack(np.broadcast_arrays(*(np.asarray(v, dtype=float)
                                         for v in (east, north, up))), axis=-1)
    p0 = np.array(_ecef(origin.latitude, origin.longitude, origin.altitude))
    x, y, z = np.moveaxis(enu @ _rotation(origin) + p0, -1, 0)
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    theta = np.arctan2(z * A, p * B)
    lat = np.arctan2(z + EP2 * B * np.sin(theta) ** 3, p - E2 * A * np.cos(theta) ** 3)
    for _ in range(2):
        sin_lat = np.sin(lat)
        n = A / np.sqrt(1.0 - E2 * sin_lat * sin_lat)
        alt = np.where(np.abs(np.cos(lat)) > 1e-9, p / np.maximum(np.cos(lat), 1e-300) - n,
                       np.abs(z) - B)
        lat = np.arctan2(z, p * (1.0 - E2 * n / (n + alt)))
    sin_lat = np.sin(lat)
    n = A / np.sqrt(1.0 - E2 * sin_lat * sin_lat)
    alt = np.where(np.abs(np.cos(lat)) > 1e-9, p / np.maximum(np.cos(lat), 1e-300) - n,
                   np.abs(z) - B)
    return np.degrees(lat), np.degrees(lon), alt
