"""An object's mass properties as the robot believes them: from its configuration, not from the simulator.

The controller compensates the held object's weight and inertia (``Payload``). It must use what it *believes*
(the configured mass, the geometry at uniform density, or the configured principal moments), because faults
change the simulated object (:mod:`pickplace.task.faults`) and the gap between the two is what they test.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from pickplace.world.objects import ObjectConfig


@dataclass(frozen=True, eq=False)
class MassProperties:
    """Mass, centre of mass and inertia of an object in its resting frame.

    Attributes:
        mass_kg: Mass (kg).
        com_m: Centre of mass (3,) in the object's frame (m).
        inertia_kg_m2: Inertia tensor (3, 3) about the centre of mass, object axes (kg m^2).
    """

    mass_kg: float
    com_m: np.ndarray
    inertia_kg_m2: np.ndarray


@functools.lru_cache(maxsize=64)
def mass_properties(obj: ObjectConfig) -> MassProperties:
    """The object's believed mass properties: ``obj.mass_kg`` spread at uniform density over its geometry (the
    centre of volume and the tessellated surface's inertia, exact for boxes, within ~0.1 % for round shapes), or
    ``obj.inertia_kg_m2`` as principal moments along the object's axes if given.
    """
    import trimesh

    geo = obj.geometry()
    mesh = trimesh.Trimesh(vertices=np.asarray(geo.vertices), faces=np.asarray(geo.faces), process=False)
    if obj.kind == "compound":  # overlapping parts would count twice in one mesh: sum the parts instead
        parts = [_part_props(p.volume_m3, p) for p in obj.primitives()]
        volume = sum(v for v, _, _ in parts)
        com = sum(v * c for v, c, _ in parts) / volume
        inertia = np.zeros((3, 3))
        for v, c, unit_inertia in parts:
            m = obj.mass_kg * v / volume
            r = c - com
            inertia += m * unit_inertia + m * (float(r @ r) * np.eye(3) - np.outer(r, r))
    else:
        density = obj.mass_kg / float(mesh.volume)
        com = np.asarray(mesh.center_mass, dtype=float)
        mesh.density = density
        inertia = np.asarray(mesh.moment_inertia, dtype=float)  # about the centre of mass, mesh axes
    if obj.inertia_kg_m2 is not None:
        inertia = np.diag(obj.inertia_kg_m2)
    for a in (com, inertia):
        a.setflags(write=False)
    return MassProperties(obj.mass_kg, com, inertia)


def _part_props(volume: float, part) -> tuple[float, np.ndarray, np.ndarray]:
    """(volume, centre (3,), inertia per unit mass about the centre, object axes (3, 3)) of a primitive."""
    s = part.size_m
    if part.kind == "box":
        a, b, c = s
        local = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) / 12.0
    elif part.kind == "cylinder":
        r, h = s
        side = (3 * r * r + h * h) / 12.0
        local = np.diag([side, side, r * r / 2.0])
    else:
        local = np.eye(3) * 2.0 * s[0] ** 2 / 5.0
    R = part.rotation
    return volume, np.asarray(part.pos_m, dtype=float), R @ local @ R.T


__all__ = ["MassProperties", "mass_properties"]
