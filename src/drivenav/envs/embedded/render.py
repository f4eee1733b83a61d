"""Perspective renderer of the embedded world: RGB, z-depth and instance semantics in one pass.

A one-floor scene (:mod:`drivenav.envs.embedded.scene`) is a structure grid whose non-free cells are full-height
opaque prisms, plus box objects, between a floor at height 0 and a ceiling. A building
(:mod:`drivenav.envs.embedded.building`) stacks such floors on slabs open at the stairwells, with its steps,
landings and railings as boxes. The camera is a level pinhole at the agent's position, the camera height above
the agent's feet (whose height the pose carries), looking along its yaw.

Every quantity is parameterised by the z-depth ``d`` (distance along the optical axis), so no cosine
correction is needed. Image column ``u`` sees the horizontal ray ``p(d) = c + d * (f + t_u * l)`` with ``f``
the heading, ``l`` the left unit vector and ``t_u = (cx - u) / fx``; image row ``v`` has height
``z(d) = h + k_v * d`` with ``k_v = (cy - v) / fy``.

Vertically the world is a stack of *spans*: the solid ground, each storey's air from its floor to its ceiling, the
slab above it (opaque except at stairwells), the next storey, ..., the solid roof. In plan a span is opaque where
its storey has a wall (or its slab is closed). Since ``z(d)`` is monotonic, a pixel's ray passes through the spans
in order: it starts in the camera's span, hits the first opaque stretch of that span's plan before it leaves the
span through its floor or ceiling plane, or else goes on into the next span at that plane -- hitting the slab's
top (a floor) or underside (a ceiling) where the slab is closed, or passing through a stairwell. The renderer
therefore

1. per column, walks the grid with an exact DDA (Amanatides & Woo; every cell the ray crosses is visited, so
   one-cell walls never leak) and records, per span, the stretches where the ray is over opaque cells (cells
   outside the grid are unknown space, opaque everywhere); one floor needs only the camera span's first stretch,
   so the walk stops at the first wall there; and slab-tests the ray against every box footprint, giving
   ``[d_in, d_out]`` and the entry face;
2. per pixel, follows its ray through the spans to the structure it hits (a wall, a floor, a ceiling, a slab's
   edge), then takes the nearest of that and each box's footprint interval intersected with its height interval
   ``{d : z0 <= z(d) <= z1}``;
3. shades the pixel's surface into the RGB image (about three quarters of a frame's cost). A world whose consumer
   may not read the RGB image asks for depth and semantics only (:meth:`Renderer.render_geometry`) and renders the
   whole frame again if the image is read: the pixels come out the same either way.

The kernels are numba-compiled and single-threaded; :class:`Renderer` holds a scene's packed arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drivenav.directions.edt import edt
from drivenav.envs.embedded import palette
from drivenav.envs.embedded.building import Box3, Building, storeys_of
from drivenav.envs.embedded.scene import Material, Scene
from drivenav.jit import jit
from drivenav.types import Pose, SimConfig

Images = tuple[NDArray[np.uint8], NDArray[np.float32], NDArray[np.int32]]

# Surface kinds of a pixel and faces of a box.
_FLOOR, _CEILING, _WALL, _OBJECT, _SLAB_EDGE = 0, 1, 2, 3, 4
_FACE_U, _FACE_V, _FACE_INSIDE, _FACE_TOP, _FACE_BOTTOM = 0, 1, 2, 3, 4

# Kinds of span (layers of the world in height).
_SOLID, _STOREY, _SLAB = 0, 1, 2
_MAX_RUNS = 64  # opaque stretches recorded per column (further ones merge into the last: opaque to the end)

# Rows of the structure colour table (passed to the kernel as data: numba would freeze global constants into
# its on-disk cache, which does not notice edits to the palette module).
_SURFACE_COLORS = (
    palette.WALL_COLOR,
    palette.BASEBOARD_COLOR,
    palette.DOOR_FRAME_COLOR,
    palette.UNKNOWN_COLOR,
    palette.CEILING_COLOR,
    palette.SLAB_EDGE_COLOR,
)
_WALL_ROW, _BASEBOARD_ROW, _DOOR_ROW, _UNKNOWN_ROW, _CEILING_ROW, _SLAB_ROW = range(6)

# Layout of the per-object geometry rows.
_GEOM_FIELDS = 8  # cx, cy, cos(yaw), sin(yaw), half sx, half sy, bottom z, top z

_AO_RANGE = 0.3  # metres from walls/furniture over which the floor darkens (contact shadow)
_FALLOFF = 0.035  # brightness = 1 / (1 + _FALLOFF * d)
_TILE = 0.5  # floor tile edge, metres
_PLANK_WIDTH, _PLANK_LENGTH = 0.18, 1.2
_WALL_PANEL = 1.2  # spacing of vertical wall panel seams, metres
_BASEBOARD = 0.1  # baseboard height, metres


class PackedScene:
    """A scene or building as the flat arrays the render kernel reads (built once per scene)."""

    def __init__(self, world: Scene | Building) -> None:
        storeys = storeys_of(world)
        grid = storeys[0].plan.grid
        self.structures: NDArray[np.uint8] = np.ascontiguousarray(
            np.stack([s.plan.structure for s in storeys]), dtype=np.uint8
        )
        self.origin = (float(grid.origin[0]), float(grid.origin[1]))
        self.resolution = float(grid.resolution)
        self.elevations: NDArray[np.float64] = np.array([s.elevation for s in storeys], np.float64)
        self._pack_spans(world)
        rooms = [room.name for s in storeys for room in s.plan.rooms]
        offsets = np.cumsum([0] + [len(s.plan.rooms) for s in storeys[:-1]])
        self.room_index: NDArray[np.int16] = np.ascontiguousarray(
            np.stack(
                [
                    np.where(s.plan.room_index > 0, s.plan.room_index + o, 0)
                    for s, o in zip(storeys, offsets, strict=True)
                ]
            ),
            dtype=np.int16,
        )
        names = ["", *rooms]
        self.floor_rgb: NDArray[np.float32] = np.array([palette.floor_color(n) for n in names], np.float32)
        self.floor_pattern: NDArray[np.int64] = np.array([palette.floor_pattern(n) for n in names], np.int64)
        self.floor_shade = np.ascontiguousarray(np.stack([_contact_shadow(s.plan) for s in storeys]))
        self.surface_rgb: NDArray[np.float32] = np.array(_SURFACE_COLORS, np.float32)
        objects = [(s.elevation, obj) for s in storeys for obj in s.plan.objects]
        boxes = world.structure_boxes if isinstance(world, Building) else ()
        n = len(objects) + len(boxes)
        self.obj_geom: NDArray[np.float64] = np.zeros((n, _GEOM_FIELDS), np.float64)
        self.obj_id: NDArray[np.int32] = np.zeros(n, np.int32)
        self.obj_rgb: NDArray[np.float32] = np.zeros((n, 3), np.float32)
        for i, (elevation, obj) in enumerate(objects):
            bottom, top = obj.elevation + elevation, obj.top + elevation
            self.obj_geom[i] = (
                obj.center[0],
                obj.center[1],
                math.cos(obj.yaw),
                math.sin(obj.yaw),
                obj.size[0] / 2.0,
                obj.size[1] / 2.0,
                bottom,
                top,
            )
            self.obj_id[i] = obj.instance_id
            self.obj_rgb[i] = palette.category_color(obj.category)
        for i, box in enumerate(boxes, start=len(objects)):
            self.obj_geom[i] = _box_geometry(box)
            self.obj_rgb[i] = palette.RAILING_COLOR if box.railing else palette.STAIR_COLOR

    def _pack_spans(self, world: Scene | Building) -> None:
        """The spans from the ground up (module docstring) and, per cell, a bit per span where it is opaque."""
        storeys = storeys_of(world)
        lo, hi, kind, storey = [-math.inf], [float(storeys[0].elevation)], [_SOLID], [0]
        opaque = np.zeros(storeys[0].plan.grid.shape, np.uint16)
        for j, s in enumerate(storeys):
            if j > 0:  # the slab under storey j, opaque but at its stairwells
                assert isinstance(world, Building)
                opaque |= np.where(world.holes[j], 0, 1 << len(lo)).astype(np.uint16)
                lo.append(world.ceiling(j - 1))
                hi.append(float(s.elevation))
                kind.append(_SLAB)
                storey.append(j)
            opaque |= np.where(s.plan.structure != Material.FREE, 1 << len(lo), 0).astype(np.uint16)
            ceiling = world.ceiling(j) if isinstance(world, Building) else float(s.plan.ceiling_height)
            lo.append(float(s.elevation))
            hi.append(ceiling)
            kind.append(_STOREY)
            storey.append(j)
        lo.append(hi[-1])
        hi.append(math.inf)
        kind.append(_SOLID)
        storey.append(len(storeys) - 1)
        if len(lo) > 16:
            raise ValueError("the renderer draws at most 7 storeys")
        self.opaque: NDArray[np.uint16] = np.ascontiguousarray(opaque)
        self.span_lo = np.array(lo, np.float64)
        self.span_hi = np.array(hi, np.float64)
        self.span_kind = np.array(kind, np.int64)
        self.span_storey = np.array(storey, np.int64)

    def camera_span(self, height: float) -> int:
        """The span holding a camera at ``height`` above the ground floor (the upper one on a boundary)."""
        inside = np.flatnonzero((self.span_lo <= height) & (height < self.span_hi))
        return int(inside[-1]) if inside.size else len(self.span_lo) - 2


def _box_geometry(box: Box3) -> tuple[float, ...]:
    x0, y0, x1, y1 = box.rect
    return ((x0 + x1) / 2.0, (y0 + y1) / 2.0, 1.0, 0.0, (x1 - x0) / 2.0, (y1 - y0) / 2.0, box.bottom, box.top)


def _contact_shadow(scene: Scene) -> NDArray[np.float32]:
    """Per-cell floor brightness factor in ``[0.7, 1]``: darker within :data:`_AO_RANGE` of an obstacle."""
    obstacles = scene.obstacle_grid(0.05)
    dist = edt(obstacles) * scene.grid.resolution
    closeness = 1.0 - np.clip(dist / _AO_RANGE, 0.0, 1.0)
    return np.ascontiguousarray(1.0 - 0.3 * closeness**2, dtype=np.float32)


class Renderer:
    """Renders RGB, z-depth and semantic images of one scene or building for a camera described by ``config``."""

    def __init__(self, scene: Scene | Building, config: SimConfig) -> None:
        self.scene = scene
        self.config = config
        self.packed = PackedScene(scene)
        intr = config.intrinsics
        self._camera = np.array(
            [config.camera_height, intr.fx, intr.fy, intr.cx, intr.cy, config.min_depth, config.max_depth],
            dtype=np.float64,
        )

    def render(self, pose: Pose) -> Images:
        """Images from the world-frame ``pose``: ``(H, W, 3)`` uint8, ``(H, W)`` float32, ``(H, W)`` int32."""
        h, w = self.config.height, self.config.width
        rgb = np.empty((h, w, 3), np.uint8)
        depth, semantic = self._draw(pose, rgb)
        return rgb, depth, semantic

    def render_geometry(self, pose: Pose) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
        """Depth and semantic images only: the same numbers as :meth:`render`'s, without shading the RGB image
        (about a quarter of a frame's cost)."""
        return self._draw(pose, np.empty((0, 0, 3), np.uint8))

    def _draw(self, pose: Pose, rgb: NDArray[np.uint8]) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
        """Run the kernel for ``pose``; it shades into ``rgb`` unless it is empty."""
        p = self.packed
        h, w = self.config.height, self.config.width
        depth = np.empty((h, w), np.float32)
        semantic = np.empty((h, w), np.int32)
        camera_z = float(pose.z) + self.config.camera_height
        _render_kernel(
            p.opaque,
            p.structures,
            p.span_lo,
            p.span_hi,
            p.span_kind,
            p.span_storey,
            p.camera_span(camera_z),
            p.elevations,
            p.origin[0],
            p.origin[1],
            p.resolution,
            p.room_index,
            p.floor_rgb,
            p.floor_pattern,
            p.floor_shade,
            p.surface_rgb,
            p.obj_geom,
            p.obj_id,
            p.obj_rgb,
            float(pose.x),
            float(pose.y),
            float(pose.yaw),
            camera_z,
            self._camera,
            rgb,
            depth,
            semantic,
        )
        return depth, semantic


def render_views(scene: Scene | Building, pose: Pose, config: SimConfig) -> Images:
    """One-off rendering (packs the scene each call; use :class:`Renderer` for many frames)."""
    return Renderer(scene, config).render(pose)


# ----------------------------------------------------------------------------------------------- kernels


@jit(inline=True)
def _opaque_bits(opaque: NDArray[np.uint16], row: int, col: int, everything: int) -> int:
    """The spans opaque at a cell (every span outside the grid: unknown space)."""
    rows, cols = opaque.shape
    if row < 0 or row >= rows or col < 0 or col >= cols:
        return everything
    return int(opaque[row, col]) & everything


@jit(inline=True)
def _material(
    structures: NDArray[np.uint8],
    span_kind: NDArray[np.int64],
    span_storey: NDArray[np.int64],
    span: int,
    row: int,
    col: int,
) -> int:
    """What a span's opaque cell is made of: its storey's structure material, 0 for a slab, unknown off the grid."""
    _, rows, cols = structures.shape
    if row < 0 or row >= rows or col < 0 or col >= cols:
        return 3  # Material.UNKNOWN
    if span_kind[span] == _SLAB:
        return 0
    return int(structures[span_storey[span], row, col])


@jit(inline=True)
def _record_changes(
    bits: int,
    current: int,
    d: float,
    face: int,
    row: int,
    col: int,
    structures: NDArray[np.uint8],
    span_kind: NDArray[np.int64],
    span_storey: NDArray[np.int64],
    open_run: NDArray[np.int64],
    u: int,
    run_in: NDArray[np.float64],
    run_out: NDArray[np.float64],
    run_face: NDArray[np.int64],
    run_mat: NDArray[np.int64],
    run_span: NDArray[np.int64],
    n: int,
) -> int:
    """Close the stretches of the spans that turn free at ``d`` and open those of the spans that turn opaque;
    returns the number of stretches recorded."""
    for s in range(span_kind.shape[0]):
        if (current & ~bits) & (1 << s):
            run_out[u, open_run[s]] = d
            open_run[s] = -1
        if (bits & ~current) & (1 << s):
            if n < run_in.shape[1]:
                run_in[u, n], run_out[u, n], run_face[u, n], run_span[u, n] = d, math.inf, face, s
                run_mat[u, n] = _material(structures, span_kind, span_storey, s, row, col)
                open_run[s] = n
                n += 1
            else:  # out of room: the last stretch of this span stays open to the end
                for k in range(n - 1, -1, -1):
                    if run_span[u, k] == s:
                        run_out[u, k] = math.inf
                        break
    return n


@jit(inline=True)
def _first_opening(
    span_kind: NDArray[np.int64],
    span: int,
    u: int,
    run_in: NDArray[np.float64],
    run_out: NDArray[np.float64],
    run_span: NDArray[np.int64],
    n_runs: int,
) -> float:
    """Where column ``u``'s ray first passes over an opening of ``span``, a slab next to the camera's span (``inf``:
    none before the grid's edge); 0 where ``span`` is no slab (nothing closes the way to it)."""
    if span < 0 or span >= span_kind.shape[0] or span_kind[span] != _SLAB:
        return 0.0
    d = 0.0
    for r in range(n_runs):
        if run_span[u, r] != span:
            continue
        if run_in[u, r] > d:
            return d
        d = max(d, run_out[u, r])
    return d


@jit(inline=True)
def _column_runs(
    opaque: NDArray[np.uint16],
    structures: NDArray[np.uint8],
    span_kind: NDArray[np.int64],
    span_storey: NDArray[np.int64],
    camera_span: int,
    everything: int,
    ox: float,
    oy: float,
    res: float,
    px: float,
    py: float,
    dx: float,
    dy: float,
    open_run: NDArray[np.int64],
    u: int,
    run_in: NDArray[np.float64],
    run_out: NDArray[np.float64],
    run_face: NDArray[np.int64],
    run_mat: NDArray[np.int64],
    run_span: NDArray[np.int64],
) -> int:
    """Exact grid DDA from ``(px, py)`` along ``(dx, dy)``, recording per span the stretches over opaque cells:
    ``run_in``/``run_out`` (ray parameters of entry and exit; ``inf`` exit: opaque to the end), the face entered
    (0: a face of constant x, 1: of constant y) and the material. Returns the number of stretches, in order of
    entry. ``everything`` has a bit for each span that is not solid; ``open_run`` is scratch space of one entry per
    span. With one such span (a one-floor scene) the walk stops at that span's first stretch."""
    rows, cols = opaque.shape
    only_camera = everything == (1 << camera_span)
    gx, gy = (px - ox) / res, (py - oy) / res
    col, row = math.floor(gx), math.floor(gy)
    inf = math.inf
    step_c = 1 if dx > 0.0 else -1
    step_r = 1 if dy > 0.0 else -1
    if dx != 0.0:
        next_x = (col + 1 - gx) if dx > 0.0 else (gx - col)
        t_max_x, t_delta_x = next_x * res / abs(dx), res / abs(dx)
    else:
        t_max_x, t_delta_x = inf, inf
    if dy != 0.0:
        next_y = (row + 1 - gy) if dy > 0.0 else (gy - row)
        t_max_y, t_delta_y = next_y * res / abs(dy), res / abs(dy)
    else:
        t_max_y, t_delta_y = inf, inf
    d, face = 0.0, 0
    current = 0
    open_run[:] = -1
    n = 0
    while True:
        outside = row < 0 or row >= rows or col < 0 or col >= cols
        bits = _opaque_bits(opaque, row, col, everything)
        if bits != current:
            n = _record_changes(
                bits,
                current,
                d,
                face,
                row,
                col,
                structures,
                span_kind,
                span_storey,
                open_run,
                u,
                run_in,
                run_out,
                run_face,
                run_mat,
                run_span,
                n,
            )
            current = bits
        if outside or (only_camera and current & (1 << camera_span)):
            return n
        if t_max_x < t_max_y:
            d, face = t_max_x, 0
            t_max_x += t_delta_x
            col += step_c
        else:
            d, face = t_max_y, 1
            t_max_y += t_delta_y
            row += step_r


@jit(inline=True)
def _box_interval(geom: NDArray[np.float64], px: float, py: float, dx: float, dy: float) -> tuple[float, float, int]:
    """Slab test of the ray against one box footprint in the box frame: ``(d_in, d_out, entry face)``.

    ``d_in > d_out`` means a miss. A ray starting inside the footprint has ``d_in = 0`` and face
    :data:`_FACE_INSIDE`.
    """
    c, s, hx, hy = geom[2], geom[3], geom[4], geom[5]
    rx, ry = px - geom[0], py - geom[1]
    ou, ov = c * rx + s * ry, -s * rx + c * ry
    du, dv = c * dx + s * dy, -s * dx + c * dy
    lo, hi, face = -math.inf, math.inf, _FACE_INSIDE
    for axis in range(2):
        o, dd, half = (ou, du, hx) if axis == 0 else (ov, dv, hy)
        if abs(dd) < 1e-12:
            if abs(o) > half:
                return 1.0, 0.0, face
            continue
        t1, t2 = (-half - o) / dd, (half - o) / dd
        if t1 > t2:
            t1, t2 = t2, t1
        if t1 > lo:
            lo, face = t1, axis
        hi = min(hi, t2)
    if lo < 0.0:
        lo, face = 0.0, _FACE_INSIDE
    return lo, hi, face


@jit(inline=True)
def _hash01(i: int, j: int) -> float:
    """A deterministic pseudo-random value in ``[0, 1)`` for an integer pair (texture variation)."""
    h = (i * 73856093) ^ (j * 19349663)
    h = (h ^ (h >> 13)) * 1274126177
    return float((h >> 8) & 1023) / 1024.0


@jit(inline=True)
def _line_weight(frac: float, width: float) -> float:
    """1 on a periodic line of ``width`` (in units of the period) centred at integer positions, else 0."""
    f = frac - math.floor(frac)
    return 1.0 if (f < width * 0.5 or f > 1.0 - width * 0.5) else 0.0


@jit(inline=True)
def _floor_shade(pattern: int, x: float, y: float, d: float, texel: float) -> float:
    """Brightness factor of the floor texture at world ``(x, y)``; line contrast fades with distance ``d``."""
    fade = min(1.0, max(0.0, 1.0 - (d - 2.5) / 3.0))
    if pattern == 0:  # tiles with grout
        tu, tv = x / _TILE, y / _TILE
        tone = 1.0 + 0.06 * (_hash01(math.floor(tu), math.floor(tv)) - 0.5)
        grout = max(_line_weight(tu, texel / _TILE), _line_weight(tv, texel / _TILE))
        return tone * (1.0 - 0.35 * fade * grout)
    if pattern == 1:  # planks running along x, staggered per row
        pv = y / _PLANK_WIDTH
        row = math.floor(pv)
        pu = x / _PLANK_LENGTH + _hash01(row, 7)
        tone = 1.0 + 0.16 * (_hash01(row, math.floor(pu)) - 0.5)
        seam = max(_line_weight(pv, texel / _PLANK_WIDTH), _line_weight(pu, texel / _PLANK_LENGTH))
        return tone * (1.0 - 0.4 * fade * seam)
    return 1.0


@jit(inline=True)
def _bilinear(grid: NDArray[np.float32], gx: float, gy: float) -> float:
    """Bilinear sample of a cell-centred grid at fractional cell coordinates (clamped to the grid)."""
    rows, cols = grid.shape
    fx = min(max(gx - 0.5, 0.0), cols - 1.0)
    fy = min(max(gy - 0.5, 0.0), rows - 1.0)
    c0, r0 = min(int(fx), cols - 2), min(int(fy), rows - 2)
    if c0 < 0 or r0 < 0:
        return float(grid[max(r0, 0), max(c0, 0)])
    ax, ay = fx - c0, fy - r0
    top = grid[r0, c0] * (1.0 - ax) + grid[r0, c0 + 1] * ax
    bottom = grid[r0 + 1, c0] * (1.0 - ax) + grid[r0 + 1, c0 + 1] * ax
    return float(top * (1.0 - ay) + bottom * ay)


@jit(inline=True)
def _box_edge_distance(geom: NDArray[np.float64], face: int, x: float, y: float, z: float) -> float:
    """Distance from a point on a box face to the nearest edge of that face (for outlines)."""
    c, s = geom[2], geom[3]
    rx, ry = x - geom[0], y - geom[1]
    eu = geom[4] - abs(c * rx + s * ry)
    ev = geom[5] - abs(-s * rx + c * ry)
    ez = min(geom[7] - z, z - geom[6])
    if face == _FACE_U:
        return float(min(ev, ez))
    if face == _FACE_V:
        return float(min(eu, ez))
    if face == _FACE_INSIDE:
        return float(ez)
    return float(min(eu, ev))


@jit()
def _beyond_camera_span(
    span_lo: NDArray[np.float64],
    span_hi: NDArray[np.float64],
    span_kind: NDArray[np.int64],
    span_storey: NDArray[np.int64],
    span: int,
    d0: float,
    cam_h: float,
    k: float,
    u: int,
    run_in: NDArray[np.float64],
    run_out: NDArray[np.float64],
    run_face: NDArray[np.int64],
    run_mat: NDArray[np.int64],
    run_span: NDArray[np.int64],
    n_runs: int,
) -> tuple[float, int, int, int, int]:
    """The structure a ray hits after leaving the camera's span at ``d0`` into ``span`` (``k`` != 0 its vertical
    slope): ``(d, kind, face, material, storey)``. A span entered over an opaque cell is hit there on a horizontal
    face (a slab's top is a floor, its underside a ceiling); else the span's first opaque stretch after ``d0``, if
    the ray meets it before leaving the span (a wall, or the edge of a slab); else the next span."""
    step = -1 if k < 0.0 else 1
    while True:
        storey = span_storey[span]
        if span_kind[span] == _SOLID:
            return d0, (_FLOOR if k < 0.0 else _CEILING), 0, 0, storey
        d1 = ((span_lo[span] if k < 0.0 else span_hi[span]) - cam_h) / k
        r = 0
        while r < n_runs and (run_span[u, r] != span or run_out[u, r] <= d0):
            r += 1
        if r < n_runs and run_in[u, r] <= d0:
            if span_kind[span] == _SLAB:
                return d0, (_FLOOR if k < 0.0 else _CEILING), 0, 0, storey
            return d0, _WALL, run_face[u, r], run_mat[u, r], storey
        if r < n_runs and run_in[u, r] < d1:
            kind = _WALL if span_kind[span] == _STOREY else _SLAB_EDGE
            return run_in[u, r], kind, run_face[u, r], run_mat[u, r], storey
        span, d0 = span + step, d1


@jit(
    "void(u2[:, ::1], u1[:, :, ::1], f8[::1], f8[::1], i8[::1], i8[::1], i8, f8[::1], f8, f8, f8, i2[:, :, ::1],"
    " f4[:, ::1], i8[::1], f4[:, :, ::1], f4[:, ::1], f8[:, ::1], i4[::1], f4[:, ::1], f8, f8, f8, f8, f8[::1],"
    " u1[:, :, ::1], f4[:, ::1], i4[:, ::1])",
)
def _render_kernel(
    opaque: NDArray[np.uint16],
    structures: NDArray[np.uint8],
    span_lo: NDArray[np.float64],
    span_hi: NDArray[np.float64],
    span_kind: NDArray[np.int64],
    span_storey: NDArray[np.int64],
    camera_span: int,
    elevations: NDArray[np.float64],
    ox: float,
    oy: float,
    res: float,
    room_index: NDArray[np.int16],
    floor_rgb: NDArray[np.float32],
    floor_pattern: NDArray[np.int64],
    floor_shade: NDArray[np.float32],
    surface_rgb: NDArray[np.float32],
    obj_geom: NDArray[np.float64],
    obj_id: NDArray[np.int32],
    obj_rgb: NDArray[np.float32],
    px: float,
    py: float,
    yaw: float,
    cam_h: float,
    camera: NDArray[np.float64],
    rgb: NDArray[np.uint8],
    depth: NDArray[np.float32],
    semantic: NDArray[np.int32],
) -> None:
    """Fill ``depth`` and ``semantic`` for a camera at ``(px, py)`` and height ``cam_h`` facing ``yaw`` (module
    doc), and shade ``rgb`` unless it is empty (the geometry of every pixel is computed the same way either way)."""
    fx, fy, ccx, ccy = camera[1], camera[2], camera[3], camera[4]
    min_d, max_d = camera[5], camera[6]
    height, width = depth.shape
    shade_rgb = rgb.size > 0
    n_obj = obj_geom.shape[0]
    _, rows, cols = structures.shape
    fwd_x, fwd_y = math.cos(yaw), math.sin(yaw)
    cam_lo, cam_hi = span_lo[camera_span], span_hi[camera_span]

    # Pass 1: per column, the opaque stretches of every span and the sorted box footprint intervals.
    ray_x = np.empty(width)
    ray_y = np.empty(width)
    everything = 0
    for s in range(span_kind.shape[0]):
        if span_kind[s] != _SOLID:
            everything |= 1 << s
    max_runs = 1 if everything == (1 << camera_span) else _MAX_RUNS
    open_run = np.empty(span_kind.shape[0], np.int64)
    run_in = np.empty((width, max_runs))
    run_out = np.empty((width, max_runs))
    run_face = np.empty((width, max_runs), np.int64)
    run_mat = np.empty((width, max_runs), np.int64)
    run_span = np.empty((width, max_runs), np.int64)
    n_runs = np.zeros(width, np.int64)
    wall_in = np.empty(width)
    wall_face = np.empty(width, np.int64)
    wall_mat = np.empty(width, np.int64)
    n_hits = np.zeros(width, np.int64)
    hit_in = np.empty((width, max(n_obj, 1)))
    hit_out = np.empty((width, max(n_obj, 1)))
    hit_obj = np.empty((width, max(n_obj, 1)), np.int64)
    hit_face = np.empty((width, max(n_obj, 1)), np.int64)
    for u in range(width):
        t = (ccx - u) / fx
        dx, dy = fwd_x - t * fwd_y, fwd_y + t * fwd_x
        ray_x[u], ray_y[u] = dx, dy
        n_runs[u] = _column_runs(
            opaque,
            structures,
            span_kind,
            span_storey,
            camera_span,
            everything,
            ox,
            oy,
            res,
            px,
            py,
            dx,
            dy,
            open_run,
            u,
            run_in,
            run_out,
            run_face,
            run_mat,
            run_span,
        )
        wall_in[u], wall_face[u], wall_mat[u] = math.inf, 0, 0
        for r in range(n_runs[u]):  # the camera span's first stretch: nothing of that span's height lies beyond it
            if run_span[u, r] == camera_span:
                wall_in[u], wall_face[u], wall_mat[u] = run_in[u, r], run_face[u, r], run_mat[u, r]
                break
        near_wall = wall_in[u]
        open_below = _first_opening(span_kind, camera_span - 1, u, run_in, run_out, run_span, n_runs[u])
        open_above = _first_opening(span_kind, camera_span + 1, u, run_in, run_out, run_span, n_runs[u])
        for o in range(n_obj):
            a, b, face = _box_interval(obj_geom[o], px, py, dx, dy)
            if a > b or b <= 0.0:
                continue
            z0, z1 = obj_geom[o, 6], obj_geom[o, 7]
            if a >= near_wall and cam_lo <= z0 and z1 <= cam_hi:
                continue  # of the camera's span, beyond its first wall
            if (z1 <= cam_lo and b <= open_below) or (z0 >= cam_hi and b <= open_above):
                continue  # below or above the camera's span, and the ray passes no opening to it before the box
            k = n_hits[u]
            while k > 0 and hit_in[u, k - 1] > a:  # insertion sort by entry distance
                hit_in[u, k], hit_out[u, k] = hit_in[u, k - 1], hit_out[u, k - 1]
                hit_obj[u, k], hit_face[u, k] = hit_obj[u, k - 1], hit_face[u, k - 1]
                k -= 1
            hit_in[u, k], hit_out[u, k], hit_obj[u, k], hit_face[u, k] = a, b, o, face
            n_hits[u] += 1

    # Pass 2: per pixel, the nearest surface, then its shade.
    color = np.empty(3)
    cam_storey = span_storey[camera_span]
    for v in range(height):
        k = (ccy - v) / fy
        if k < 0.0:
            cam_exit, next_span = (cam_lo - cam_h) / k, camera_span - 1
        elif k > 0.0:
            cam_exit, next_span = (cam_hi - cam_h) / k, camera_span + 1
        else:
            cam_exit, next_span = math.inf, camera_span
        plane_kind = _FLOOR if k <= 0.0 else _CEILING
        onward = k != 0.0 and span_kind[next_span] != _SOLID
        for u in range(width):
            best, kind, obj, face, mat, storey = cam_exit, plane_kind, -1, 0, 0, cam_storey
            if wall_in[u] < best:  # the camera span's first wall, before the ray leaves the span
                best, kind, face, mat = wall_in[u], _WALL, wall_face[u], wall_mat[u]
            elif onward:  # through the floor or ceiling plane, where the slab may be open
                best, kind, face, mat, storey = _beyond_camera_span(
                    span_lo,
                    span_hi,
                    span_kind,
                    span_storey,
                    next_span,
                    cam_exit,
                    cam_h,
                    k,
                    u,
                    run_in,
                    run_out,
                    run_face,
                    run_mat,
                    run_span,
                    n_runs[u],
                )
            for hh in range(n_hits[u]):
                a = hit_in[u, hh]
                if a >= best:
                    break
                o = hit_obj[u, hh]
                z0, z1 = obj_geom[o, 6], obj_geom[o, 7]
                if k > 0.0:
                    c, e = (z0 - cam_h) / k, (z1 - cam_h) / k
                elif k < 0.0:
                    c, e = (z1 - cam_h) / k, (z0 - cam_h) / k
                elif z0 <= cam_h <= z1:
                    c, e = -math.inf, math.inf
                else:
                    continue
                lo = max(a, c)
                if lo <= min(hit_out[u, hh], e) and lo < best:
                    best, kind, obj = lo, _OBJECT, o
                    face = (_FACE_TOP if k < 0.0 else _FACE_BOTTOM) if c > a else hit_face[u, hh]

            depth[v, u] = min(max(best, min_d), max_d)
            semantic[v, u] = obj_id[obj] if kind == _OBJECT else 0
            if not shade_rgb:
                continue
            hx, hy, hz = px + best * ray_x[u], py + best * ray_y[u], cam_h + k * best
            texel = 1.5 * best / fx  # about 1.5 pixels in metres at this depth
            if kind == _FLOOR:
                gx, gy = (hx - ox) / res, (hy - oy) / res
                r = min(max(math.floor(gy), 0), rows - 1)
                cc = min(max(math.floor(gx), 0), cols - 1)
                room = room_index[storey, r, cc]
                shade = _floor_shade(floor_pattern[room], hx, hy, best, texel)
                shade *= _bilinear(floor_shade[storey], gx, gy)
                for ch in range(3):
                    color[ch] = floor_rgb[room, ch] * shade
            elif kind == _CEILING:
                for ch in range(3):
                    color[ch] = surface_rgb[_CEILING_ROW, ch]
            elif kind == _SLAB_EDGE:
                shade = 0.86 if face == 0 else 1.0
                for ch in range(3):
                    color[ch] = surface_rgb[_SLAB_ROW, ch] * shade
            elif kind == _WALL:
                shade = 0.86 if face == 0 else 1.0
                if mat == Material.WALL:
                    along = hy if face == 0 else hx
                    seam = _line_weight(along / _WALL_PANEL, texel / _WALL_PANEL)
                    row = _BASEBOARD_ROW if hz - elevations[storey] < _BASEBOARD else _WALL_ROW
                    shade *= 1.0 - 0.12 * seam
                elif mat == Material.DOOR_FRAME:
                    row = _DOOR_ROW
                else:
                    row = _UNKNOWN_ROW
                for ch in range(3):
                    color[ch] = surface_rgb[row, ch] * shade
            else:
                if face == _FACE_TOP:
                    shade = 1.0
                elif face == _FACE_U:
                    shade = 0.78
                elif face == _FACE_V:
                    shade = 0.62
                else:
                    shade = 0.5
                lum = 0.3 * obj_rgb[obj, 0] + 0.59 * obj_rgb[obj, 1] + 0.11 * obj_rgb[obj, 2]
                on_edge = _box_edge_distance(obj_geom[obj], face, hx, hy, hz) < texel
                for ch in range(3):
                    value = obj_rgb[obj, ch] * shade
                    if on_edge:
                        value = value * 0.45 if lum > 70.0 else value + 90.0
                    color[ch] = value
            light = 1.0 / (1.0 + _FALLOFF * best)
            for ch in range(3):
                rgb[v, u, ch] = np.uint8(min(255.0, max(0.0, color[ch] * light)))
