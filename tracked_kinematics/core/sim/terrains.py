"""
Named terrains for the simulator: the soil's Coulomb friction along and across the tracks.

``mu_y / mu_x`` sets the slip in turns (chi); the coefficients are our assumptions, chosen to span
the chi of the real recordings, not measurements. See docs/simulator.md.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from .dynamics import Vehicle


@dataclass(frozen=True, slots=True)
class Terrain:
    """Friction of one soil: ``mu_x``, ``mu_y`` along and across the tracks (> 0)."""

    name: str
    mu_x: float
    mu_y: float
    description: str = ''

    def apply(self, vehicle: Vehicle) -> Vehicle:
        """Return ``vehicle`` on this terrain: the same geometry, this friction."""
        return replace(vehicle, mu_x=self.mu_x, mu_y=self.mu_y)


TERRAINS: dict[str, Terrain] = {terrain.name: terrain for terrain in (
    Terrain('hard_floor', 0.6, 0.75, 'indoor floor (the Auriga-alpha file: chi 0.51)'),
    Terrain('asphalt', 0.8, 0.85, 'dry asphalt: high grip both ways (chi 0.56)'),
    Terrain('gravel', 0.5, 0.8, 'loose gravel: the belts slide sideways less easily (chi 0.42)'),
    Terrain('grass', 0.45, 0.85, 'grass: low grip along, high resistance across (chi 0.36)'),
    Terrain('ice', 0.1, 0.12, 'ice: little grip at all (chi 0.53, but it slides in turns)'),
)}
"""The shipped terrains (chi of the Auriga-alpha on each, 11 x 11 map, in parentheses)."""
