"""Object placement with room-type priors.

Each room receives its type's anchor objects (a bedroom's bed, a bathroom's toilet and sink) and then a
Poisson number of further objects, proportional to its floor area, drawn from the categories' room-type priors
(:mod:`drivenav.envs.vocabulary`). Scenes without rooms (ROS building maps) are treated as one space of unknown
type with the generic prior. Objects go where their category's style says: backed against a wall and facing
into the room (the object's local +y axis is the wall's inward normal), slid into a corner, in open floor,
mounted on a wall, or on top of a host object.

Every accepted object lies in free space, inside its room, clear of door frames and of other objects (boxes
may share a footprint only when their heights do not overlap: a picture over a sofa). An object low enough to
block the agent is accepted only if it keeps the navigable space's components intact: the navigable cells it
removes are computed exactly (a disk of the agent radius around its footprint, as in
:meth:`Scene.navigable_grid`) and every navigable cell next to them must stay in one local component.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.directions.edt import edt
from drivenav.envs.embedded.geodesic import largest_component
from drivenav.envs.embedded.scene import Material, ObjectInstance, Scene
from drivenav.envs.vocabulary import VOCABULARY, CategorySpec, PlacementStyle, Vocabulary
from drivenav.errors import InputError
from drivenav.grid import GridSpec, wrap_angle
from drivenav.types import SimConfig

_AGENT = SimConfig()
_GAP = 0.5  # cells between an object and the wall it stands against
_DOOR_KEEPOUT = 0.75  # metres around door frames kept clear of objects
_REACH = 1.0  # metres: objects go within this distance of the main navigable component, in its free space
_CHECK_PAD = 1.5  # metres around a blocking object searched by the connectivity check
_CENTER_CLEARANCE = 0.45  # metres between a free-standing object and the walls
_WALL_BAND = 2.5  # cells: candidate cells for wall objects lie this close to a wall
_SLIDE_RANGE = 4.0  # metres searched along a wall for a corner
_AXIS_SNAP = math.radians(15.0)  # wall normals this close to the map's wall axes are snapped to them
_ATTEMPTS = 6  # positions tried per category choice
_MAX_FAILURES = 2  # failed choices before a category is dropped for a room
_MAX_OBJECTS_PER_REGION = 500
_ROOM_AREA = 25.0  # m^2 of open space that counts as one room for the per-room category caps


@dataclass
class _Region:
    """Where objects of one room go: candidate cells sorted by distance to the nearest wall."""

    index: int  # value of the region in the room-index grid (0 for a scene without rooms)
    room_type: str | None
    cells: NDArray[np.int64]
    wall_dist: NDArray[np.float64]
    counts: NDArray[np.int64]  # objects placed per category (vocabulary order)
    placed: list[ObjectInstance] = field(default_factory=list)


def place_objects(
    scene: Scene,
    rng: np.random.Generator,
    density: float = 1.0,
    free_standing: Mapping[str, tuple[str, ...]] | None = None,
    keep_clear: NDArray[np.bool_] | None = None,
) -> list[ObjectInstance]:
    """Place objects in ``scene`` (whose ``objects`` are ignored) using its rooms' types as priors.

    Scenes without rooms use a generic indoor prior. Returned objects lie in free space, do not overlap walls
    or each other, and keep the navigable space connected. ``density`` scales the number of objects.
    ``free_standing`` maps a room type to categories placed first in that room's open floor, whatever their
    usual style (a sofa or a bookshelf dividing an open-plan living area, a kitchen island): furniture that
    partly blocks views and passages. ``None`` (the default) places none and draws nothing for them.
    ``keep_clear`` marks free cells no object may cover (the floor before and after a flight of stairs).
    """
    if not (isinstance(density, int | float) and math.isfinite(density) and density >= 0.0):
        raise InputError("place_objects", "density", "a finite non-negative number", density)
    placer = _Placer(scene, rng, VOCABULARY)
    if keep_clear is not None:
        placer.blocked |= keep_clear
    if density > 0.0:
        for region in placer.regions:
            if free_standing is not None and region.room_type is not None:
                for name in free_standing.get(region.room_type, ()):
                    placer.place_free_standing(region, name)
            placer.fill(region, density)
    return placer.objects


class _Placer:
    """Occupancy and navigability state while objects are added one by one."""

    def __init__(self, scene: Scene, rng: np.random.Generator, vocab: Vocabulary) -> None:
        self.grid: GridSpec = scene.grid
        self.res = scene.grid.resolution
        self.rng = rng
        self.vocab = vocab
        self.free = scene.structure == Material.FREE
        # scipy's arrays, scaled in place and kept as int32 (no grid-sized copies: the worker-memory goal).
        wall_dist: NDArray[np.float64]
        self.nearest: NDArray[np.int32]
        wall_dist, self.nearest = ndimage.distance_transform_edt(self.free, return_indices=True)
        wall_dist *= self.res
        self.axis = _dominant_axis(self.free, wall_dist, self.nearest, self.res)
        self.nav = replace(scene, objects=[]).navigable_grid(_AGENT.agent_radius, _AGENT.agent_height).copy()
        self.blocked = ~self.free | _near(scene.structure == Material.DOOR_FRAME, _DOOR_KEEPOUT, self.res)
        self.room_index = scene.room_index if scene.rooms else np.zeros(self.grid.shape, dtype=np.int16)
        self.objects: list[ObjectInstance] = []
        self.spec_index = {spec.name: k for k, spec in enumerate(vocab.specs)}
        self.regions = self._regions(scene, self._reachable(), wall_dist)
        del wall_dist  # the regions keep their cells' distances; the grids below are made after it goes
        self.floor_top = np.zeros(self.grid.shape, dtype=np.float64)
        self.mounted_bottom = np.full(self.grid.shape, np.inf)
        self.on_surface = np.zeros(self.grid.shape, dtype=bool)

    def _reachable(self) -> NDArray[np.bool_]:
        """Free cells near the main navigable component and in the same piece of free space (no sealed rooms)."""
        main = largest_component(self.nav)
        pieces, _ = ndimage.label(self.free)
        connected = np.isin(pieces, np.unique(pieces[main]))
        return connected & _near(main, _REACH, self.res)

    def _regions(self, scene: Scene, allowed: NDArray[np.bool_], wall_dist: NDArray[np.float64]) -> list[_Region]:
        if not scene.rooms:
            return [self._region(0, None, allowed, wall_dist)]
        return [
            self._region(k + 1, room.name, allowed & (self.room_index == k + 1), wall_dist)
            for k, room in enumerate(scene.rooms)
        ]

    def _region(
        self, index: int, room_type: str | None, mask: NDArray[np.bool_], wall_dist: NDArray[np.float64]
    ) -> _Region:
        cells = np.flatnonzero(mask)
        dist = wall_dist.ravel()[cells]
        order = np.argsort(dist, kind="stable")
        room = room_type if room_type in self.vocab.room_types else None
        return _Region(index, room, cells[order], dist[order], np.zeros(len(self.vocab.specs), dtype=np.int64))

    # ----------------------------------------------------------------------------------- what to place

    def fill(self, region: _Region, density: float) -> None:
        """Anchors first, then a Poisson number of objects drawn from the region's prior."""
        area = len(region.cells) * self.res**2
        if area == 0.0:
            return
        specs = self.vocab.specs
        rate = self.vocab.generic_density
        anchors: tuple[str, ...] = ()
        if region.room_type is not None:
            rate = self.vocab.density.get(region.room_type, rate)
            anchors = self.vocab.anchors.get(region.room_type, ())
        for name in anchors:
            self._place(region, self.vocab.spec(name))
        wanted = min(int(self.rng.poisson(density * rate * area)), _MAX_OBJECTS_PER_REGION)
        weights = np.array([spec.prior(region.room_type) for spec in specs])
        # Caps are per room; open space of unknown type (a building without rooms) counts as several rooms.
        rooms_worth = math.ceil(area / _ROOM_AREA) if region.room_type is None else 1
        limits = np.array([spec.max_per_room for spec in specs]) * rooms_worth
        failures = np.zeros(len(specs), dtype=np.int64)
        placed = 0
        for _ in range(3 * wanted):
            if placed >= wanted:
                break
            open_weights = weights * (region.counts < limits) * (failures < _MAX_FAILURES)
            if open_weights.sum() <= 0.0:
                break
            k = int(self.rng.choice(len(specs), p=open_weights / open_weights.sum()))
            if self._place(region, specs[k]):
                placed += 1
            else:
                failures[k] += 1

    def place_free_standing(self, region: _Region, name: str) -> bool:
        """Place one ``name`` object in the region's open floor (the centre style), clear of the walls."""
        return self._place(region, replace(self.vocab.spec(name), style=PlacementStyle.CENTER))

    def _place(self, region: _Region, spec: CategorySpec) -> bool:
        for _ in range(_ATTEMPTS):
            candidate = self._propose(region, spec)
            if candidate is not None and self._commit(region, spec, candidate):
                return True
        return False

    # ------------------------------------------------------------------------------------ where to put it

    def _propose(self, region: _Region, spec: CategorySpec) -> ObjectInstance | None:
        size = spec.sample_size(self.rng)
        if spec.style is PlacementStyle.SURFACE:
            return self._on_host(region, spec, size)
        if spec.style is PlacementStyle.CENTER:
            cell = self._pick(region, max(size[0], size[1]) / 2.0 + _CENTER_CLEARANCE, math.inf)
            if cell is None:
                return None
            normal = self._wall_normal(cell)
            base = self.axis if normal is None else math.atan2(normal[1], normal[0])
            yaw = base + 0.5 * math.pi * int(self.rng.integers(4))
            return self._instance(spec, self._cell_xy(cell), size, yaw, spec.sample_elevation(self.rng))
        cell = self._pick(region, 0.0, _WALL_BAND * self.res)
        normal = None if cell is None else self._wall_normal(cell)
        if cell is None or normal is None:
            return None
        wall = self.grid.cell_to_world(self._nearest_wall(cell))
        centre = wall + normal * ((0.5 + _GAP) * self.res + size[1] / 2.0)
        if spec.style is PlacementStyle.CORNER:
            tangent = np.array([-normal[1], normal[0]]) * (1.0 if self.rng.random() < 0.5 else -1.0)
            centre = self._slide(centre, tangent, size[0])
        yaw = math.atan2(normal[1], normal[0]) - 0.5 * math.pi
        return self._instance(spec, centre, size, yaw, spec.sample_elevation(self.rng))

    def _instance(
        self,
        spec: CategorySpec,
        centre: NDArray[np.float64],
        size: tuple[float, float, float],
        yaw: float,
        elevation: float,
    ) -> ObjectInstance:
        return ObjectInstance(0, spec.name, (float(centre[0]), float(centre[1])), size, wrap_angle(yaw), elevation)

    def _pick(self, region: _Region, low: float, high: float) -> int | None:
        """A random candidate cell whose wall distance lies in ``[low, high]``."""
        a = int(np.searchsorted(region.wall_dist, low, side="left"))
        b = int(np.searchsorted(region.wall_dist, high, side="right"))
        return int(region.cells[self.rng.integers(a, b)]) if b > a else None

    def _cell_xy(self, cell: int) -> NDArray[np.float64]:
        return self.grid.cell_to_world(np.array(divmod(cell, self.grid.shape[1])))

    def _nearest_wall(self, cell: int) -> NDArray[np.int32]:
        r, c = divmod(cell, self.grid.shape[1])
        return self.nearest[:, r, c]

    def _wall_normal(self, cell: int) -> NDArray[np.float64] | None:
        """Unit inward normal of the nearest wall, snapped to the map's wall axes; ``None`` if off-axis."""
        r, c = divmod(cell, self.grid.shape[1])
        wall_r, wall_c = self._nearest_wall(cell)
        angle = math.atan2(r - wall_r, c - wall_c)
        quarter = 0.5 * math.pi
        snapped = self.axis + quarter * round((angle - self.axis) / quarter)
        if abs(wrap_angle(angle - snapped)) > _AXIS_SNAP:
            return None
        return np.array([math.cos(snapped), math.sin(snapped)])

    def _slide(self, centre: NDArray[np.float64], direction: NDArray[np.float64], width: float) -> NDArray[np.float64]:
        """Move a wall object along the wall (``direction``) until its side meets the next wall."""
        steps = np.arange(1, int(_SLIDE_RANGE / (0.5 * self.res))) * (0.5 * self.res)
        cells = self.grid.world_to_cell(centre + steps[:, None] * direction)
        inside = self.grid.contains(cells)
        rows = np.clip(cells[:, 0], 0, self.grid.shape[0] - 1)
        cols = np.clip(cells[:, 1], 0, self.grid.shape[1] - 1)
        hit = ~inside | ~self.free[rows, cols]
        if not hit.any():
            return centre
        reach = float(steps[int(np.argmax(hit))]) - 0.25 * self.res - _GAP * self.res - width / 2.0
        moved: NDArray[np.float64] = centre + direction * reach
        return moved

    def _on_host(self, region: _Region, spec: CategorySpec, size: tuple[float, float, float]) -> ObjectInstance | None:
        hosts = [o for o in region.placed if o.category in spec.hosts]
        if not hosts:
            return None
        host = hosts[int(self.rng.integers(len(hosts)))]
        slack_u, slack_v = host.size[0] - size[0], host.size[1] - size[1]
        if slack_u < 2.0 * self.res or slack_v < 2.0 * self.res:
            return None
        u = self.rng.uniform(-0.5, 0.5) * (slack_u - 2.0 * self.res)
        v = self.rng.uniform(-0.5, 0.5) * (slack_v - 2.0 * self.res)
        c, s = math.cos(host.yaw), math.sin(host.yaw)
        centre = np.array([host.center[0] + c * u - s * v, host.center[1] + s * u + c * v])
        return self._instance(spec, centre, size, host.yaw, host.top)

    # ------------------------------------------------------------------------------------- acceptance

    def _commit(self, region: _Region, spec: CategorySpec, obj: ObjectInstance) -> bool:
        """Accept ``obj`` if it fits (free, in its room, no clash) and keeps navigation connected."""
        window = self._window(obj, 1, clip=False)
        if window is None:
            return False
        gx, gy = self._centres(window)
        # Grown by half a cell diagonal: any overlap between two footprints covers some marked cell centre.
        mask = obj.contains(gx, gy, margin=0.71 * self.res)
        if not mask.any() or self.blocked[window][mask].any():
            return False
        if (self.room_index[window][mask] != region.index).any() or self._clashes(spec, obj, window, mask):
            return False
        if obj.blocks(_AGENT.agent_height) and not self._cut_navigable(obj):
            return False
        self._occupy(spec, obj, window, mask)
        placed = replace(obj, instance_id=len(self.objects) + 1)
        self.objects.append(placed)
        region.placed.append(placed)
        region.counts[self.spec_index[obj.category]] += 1
        return True

    def _clashes(
        self, spec: CategorySpec, obj: ObjectInstance, window: tuple[slice, slice], mask: NDArray[np.bool_]
    ) -> bool:
        """Whether ``obj`` overlaps a placed object in 3-D (floor objects, wall-mounted ones, surface items)."""
        floor_top = self.floor_top[window][mask]
        mounted_bottom = self.mounted_bottom[window][mask]
        if spec.style is PlacementStyle.MOUNTED:
            return bool(np.isfinite(mounted_bottom).any() or (floor_top > obj.elevation).any())
        below = self.on_surface[window][mask] if spec.style is PlacementStyle.SURFACE else floor_top > 0.0
        return bool(below.any() or (mounted_bottom < obj.top).any())

    def _occupy(
        self, spec: CategorySpec, obj: ObjectInstance, window: tuple[slice, slice], mask: NDArray[np.bool_]
    ) -> None:
        if spec.style is PlacementStyle.MOUNTED:
            view = self.mounted_bottom[window]
            view[mask] = np.minimum(view[mask], obj.elevation)
            return
        if spec.style is PlacementStyle.SURFACE:
            self.on_surface[window][mask] = True
        view = self.floor_top[window]
        view[mask] = np.maximum(view[mask], obj.top)

    def _cut_navigable(self, obj: ObjectInstance) -> bool:
        """Remove the navigable cells ``obj`` blocks, unless that would split a navigable component.

        Exact local update of :meth:`Scene.navigable_grid`: a cell stays navigable iff it clears every obstacle
        cell by the agent radius, so the cells lost are those too close to the object's obstacle cells
        (found with the scene's own rule on a window holding only them). The cut is safe if all navigable
        cells bordering the lost ones share one component of the window around them (then every path through
        the lost cells can be rerouted).
        """
        pad = 2 * math.ceil(_AGENT.agent_radius / self.res) + math.ceil(_CHECK_PAD / self.res)
        window = self._window(obj, pad, clip=True)
        assert window is not None
        gx, gy = self._centres(window)
        footprint = obj.contains(gx, gy, margin=0.5 * self.res)
        origin = (gx[0, 0] - 0.5 * self.res, gy[0, 0] - 0.5 * self.res)
        local_grid = GridSpec(self.res, (float(origin[0]), float(origin[1])), footprint.shape)
        local = Scene("", local_grid, np.where(footprint, Material.WALL, Material.FREE).astype(np.uint8))
        near = ~local.navigable_grid(_AGENT.agent_radius, _AGENT.agent_height)
        nav = self.nav[window]
        lost = nav & near
        if not lost.any():
            return True
        kept = nav & ~lost
        labels, _ = ndimage.label(kept)
        border = labels[ndimage.binary_dilation(lost) & kept]
        if border.size == 0 or (border != border[0]).any():
            return False
        self.nav[window] = kept
        return True

    def _window(self, obj: ObjectInstance, pad: int, clip: bool) -> tuple[slice, slice] | None:
        """Grid slices around ``obj``'s footprint, ``pad`` cells wider; ``None`` if unclipped and off the grid."""
        corners = obj.footprint()
        lo = self.grid.world_to_cell(corners.min(axis=0)) - pad - 1
        hi = self.grid.world_to_cell(corners.max(axis=0)) + pad + 2
        rows, cols = self.grid.shape
        if not clip and (lo.min() < 0 or hi[0] > rows or hi[1] > cols):
            return None
        return slice(max(int(lo[0]), 0), min(int(hi[0]), rows)), slice(max(int(lo[1]), 0), min(int(hi[1]), cols))

    def _centres(self, window: tuple[slice, slice]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World x, y of the cell centres in ``window`` (same arithmetic as :meth:`GridSpec.cell_centers`)."""
        ox, oy = self.grid.origin
        xs = ox + (np.arange(window[1].start, window[1].stop) + 0.5) * self.res
        ys = oy + (np.arange(window[0].start, window[0].stop) + 0.5) * self.res
        gx, gy = np.meshgrid(xs, ys)
        return gx, gy


def _near(mask: NDArray[np.bool_], radius: float, res: float) -> NDArray[np.bool_]:
    """Cells within ``radius`` metres of a cell of ``mask`` (none if the mask is empty)."""
    if not mask.any():
        return np.zeros_like(mask)
    result: NDArray[np.bool_] = edt(mask) * res <= radius
    return result


def _dominant_axis(
    free: NDArray[np.bool_], wall_dist: NDArray[np.float64], nearest: NDArray[np.int32], res: float
) -> float:
    """The map's wall orientation modulo 90 degrees, in ``[-45, 45)`` degrees (0 for axis-aligned plans).

    The most common direction, in 1-degree bins, of the vectors from wall-adjacent cells to their nearest
    wall cell; the mean within that bin.
    """
    rows, cols = np.nonzero(free & (wall_dist <= 1.5 * res))
    if rows.size == 0:
        return 0.0
    angles = np.arctan2(rows - nearest[0, rows, cols], cols - nearest[1, rows, cols])
    folded = np.mod(angles + 0.25 * math.pi, 0.5 * math.pi) - 0.25 * math.pi
    bins = np.clip(((folded + 0.25 * math.pi) / math.radians(1.0)).astype(np.int64), 0, 89)
    mode = int(np.argmax(np.bincount(bins, minlength=90)))
    return float(folded[bins == mode].mean())
