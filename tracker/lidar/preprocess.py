"""Body-frame LiDAR returns -> world-frame returns that may belong to objects on the water (paper sec. 2.1).

Order matters for cost: the cheap per-point masks (finite, range, own boat, height) run first, so the neighbour
search for spray only sees the few low returns that survive them.

Frames: input body FRD (x bow, y starboard, z down), metres, with the boat's pose in world NED per point (or one
pose for all); output world NED. Heights are "above the water surface", up positive.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from tracker.ego import PoseTable
from tracker.grouping import expand_groups, group_keys
from tracker.lidar.config import PreprocessConfig
from tracker.lidar.coverage import BIN_CENTRES, N_BINS, RING_COLUMNS, BeamGeometry, band_intervals
from tracker.lidar.range_image import RINGS, RangeImage
from tracker.lidar.water import WaterEstimate, WaterSurface
from tracker.obstacle_map import bearing_bins

log = logging.getLogger(__name__)

# Why a return was dropped (PreprocessResult.reason), one code per point; the first rule that dropped it wins.
KEPT, NONFINITE, RANGE, OWN_BOAT, HEIGHT, WATER, ISOLATED, SPRAY = range(8)
REASON_NAMES = ("kept", "nonfinite", "range", "own_boat", "height", "water", "isolated", "spray")


@dataclass
class PreprocessResult:
    points_world: np.ndarray  # (M, 3) world NED, m: the returns kept
    keep: np.ndarray  # (N,) bool over the input points
    n_nonfinite: int = 0
    n_range: int = 0  # outside [min_range, max_range]
    n_own_boat: int = 0
    n_height: int = 0  # outside [min_height, max_height] above the water
    n_spray: int = 0  # low and isolated: water surface or spray
    n_water: int = 0  # within the sea margin of the estimated water surface
    n_isolated: int = 0  # alone in the range image: rain drops, spray droplets
    n_grazing: int = 0  # within the sea margin but solid: a solid's foot in calm water (see preprocess)
    water: WaterEstimate = field(default_factory=WaterEstimate)
    # (L, 3) world NED: returns within the sea margin yet above its floor (at any height in it beyond the config's
    # waterline_gate_range), not alone in the range image, and within the spray range only on a face: a crest's top
    # or a hull's lower strakes or waterline; only a known hull around them can tell which
    within_margin_world: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # (L,) bool: whether each came back on a laser whose sea the grazing-line rule judged sparse (empty where that
    # rule did not judge: a calm sea, or no range image)
    within_margin_sparse: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    # (F, 3) world NED: returns within the sea margin on a line along one laser with a kept return (config
    # solid_line_min_run): a solid's foot for the obstacle array, not evidence for the tracker, which the kept part
    # of the line already gives (counted under n_water)
    feet_world: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # (N,) int8 over the input points, KEPT or the rule that dropped each one; only with preprocess(reasons=True)
    # (the live view asks for it), so the boat's hot path never builds it.
    reason: np.ndarray | None = None

    def counts(self) -> dict[str, int]:
        """Returns kept and dropped, by rule (REASON_NAMES order); they add up to the revolution's points."""
        kept = int(self.points_world.shape[0])
        n = (self.n_nonfinite, self.n_range, self.n_own_boat, self.n_height, self.n_water, self.n_isolated)
        return dict(zip(REASON_NAMES, (kept, *n, self.n_spray), strict=True))


_LASER_STEP_TAN = float(np.tan(np.radians(2.0)))  # VLP-16 lasers' elevation step (vlp16.md)
_EXACT_BELOW = 10  # cube counts under 10x the minimum get an exact ball count (dense surfaces never need one)
_OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], dtype=np.int64)


class CubeGrid:
    """Points pooled into cubes of side ``radius``, for counting each query point's neighbours with sorts, not a
    tree walk. A k-d tree ball query costs per neighbour: a wall 5 m away gives every return hundreds of neighbours
    within 0.5 m and 29k queries took 150 ms; so did building a tree over a whole revolution for a few queries."""

    def __init__(self, points: np.ndarray, radius: float) -> None:
        if len(points) == 0:
            raise ValueError("CubeGrid needs at least one point")
        self.points = points
        self.radius = radius
        cells = [np.floor((points[:, k] - points[:, k].min()) * (1.0 / radius)).astype(np.int64) + 1 for k in range(3)]
        self.span = [int(c.max()) + 2 for c in cells]
        self.cells = cells
        keys = self._key(*cells)
        self.order, self.starts, self.count, self.cube_of = group_keys(keys)
        self.keys = keys[self.order[self.starts]]  # one per occupied cube, sorted

    def _key(self, i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
        return (i * self.span[1] + j) * self.span[2] + k

    def _neighbour_cubes(self, cubes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For occupied ``cubes``: (which of them, which occupied cube) for every occupied cube of the 3x3x3 block."""
        first = self.order[self.starts[cubes]]
        ci, cj, ck = (np.take(c, first) for c in self.cells)
        nk = self._key(
            ci[:, None] + _OFFSETS[None, :, 0], cj[:, None] + _OFFSETS[None, :, 1], ck[:, None] + _OFFSETS[None, :, 2]
        ).ravel()
        pos = np.minimum(np.searchsorted(self.keys, nk), self.keys.size - 1)
        hit = self.keys[pos] == nk
        return np.repeat(np.arange(cubes.size), _OFFSETS.shape[0])[hit], pos[hit]

    def upper_counts(self, query_idx: np.ndarray) -> np.ndarray:
        """For each query ``points[query_idx]``, how many OTHER points lie in the 3 x 3 x 3 block of cubes around
        its cube: a box of about 1.5 x radius either way, so an upper bound of the count within ``radius``."""
        if query_idx.size == 0:
            return np.zeros(0, dtype=np.int64)
        # Work per occupied query cube, not per query point: dense surfaces put dozens of returns in one cube.
        wanted = np.zeros(self.keys.size, dtype=bool)
        wanted[self.cube_of[query_idx]] = True
        q = np.flatnonzero(wanted)
        which, cube = self._neighbour_cubes(q)
        total = np.zeros(self.keys.size, dtype=np.int64)
        total[q] = np.bincount(which, weights=self.count[cube], minlength=q.size).astype(np.int64)
        return total[self.cube_of[query_idx]] - 1

    def exact_counts(self, query_idx: np.ndarray) -> np.ndarray:
        """For each query, how many OTHER points lie within ``radius`` (3-D). Meant for few queries with few
        neighbours: it measures every point of the 27 cubes around each query."""
        if query_idx.size == 0:
            return np.zeros(0, dtype=np.int64)
        which, cube = self._neighbour_cubes(self.cube_of[query_idx])
        # every (query, candidate point) pair: the candidate cubes' members, query by query
        members = expand_groups(self.order, self.starts, self.count, cube)
        owner = np.repeat(which, self.count[cube])
        d = np.take(self.points, members, axis=0) - np.take(self.points, query_idx[owner], axis=0)
        near = np.einsum("ij,ij->i", d, d) <= self.radius * self.radius
        return np.bincount(owner[near], minlength=query_idx.size) - 1


def preprocess(
    xyz_body: np.ndarray,
    position_ned: np.ndarray,
    roll: np.ndarray | float,
    pitch: np.ndarray | float,
    yaw: np.ndarray | float,
    config: PreprocessConfig | None = None,
    pose_index: np.ndarray | None = None,
    water: WaterSurface | None = None,
    t: float = 0.0,
    ring: np.ndarray | None = None,
    point_t: np.ndarray | None = None,
    reasons: bool = False,
    beams: BeamGeometry | None = None,
    bins: np.ndarray | None = None,
    on_hull: Callable[[np.ndarray], np.ndarray] | None = None,
) -> PreprocessResult:
    """Filter one revolution and move it to the world frame.

    ``position_ned`` is (3,) or (K, 3): the body origin in world NED; ``roll``, ``pitch``, ``yaw`` are scalars or
    (K,) arrays (radians, body->NED, aerospace Z-Y-X). Point i takes pose ``pose_index[i]``, or, without
    ``pose_index``, pose i (K = N) or the one pose for all. With ``water`` (kept by the caller across
    revolutions, ``t`` the revolution's time), heights are taken above the water surface estimated from this
    revolution's own water returns and the sea margin follows the measured sea state; without it the configured
    waterline and ``cfg.water.margin_floor`` apply. ``ring`` (laser 0 = lowest, per point) lets the estimate tell
    water, which every lower beam meets, from one beam's line along a quay face. With ``ring`` and the firing
    times ``point_t`` the revolution's range image (range_image.py) also drops lone returns (rain, spray) and keeps
    returns on vertical faces out of the water estimate; without them those two rules are not applied.
    ``reasons`` also returns, per point, the rule that dropped it (PreprocessResult.reason). ``beams`` (where the
    revolution's beams pointed, coverage.BeamGeometry) lets the grazing-line rule judge each laser's water returns
    against the firings that met the water (see _grazing_lines). ``bins`` (N,), the obstacle-array bin of each
    return (obstacle_map.bearing_bins of its body x and y), spares that rule computing them again. ``on_hull`` (world
    north, east (K, 2) -> (K,) bool) says which places lie on a hull the tracker holds: returns there are not the sea,
    whatever their height, and do not set its margin.
    """
    cfg = config or PreprocessConfig()
    xyz = np.asarray(xyz_body, dtype=float).reshape(-1, 3)
    n = xyz.shape[0]
    poses = PoseTable.of(position_ned, roll, pitch, yaw, n, pose_index)
    # The columns copied once: every pass below reads them contiguously (a strided column costs 2.5x a pass).
    x, y, z = np.ascontiguousarray(xyz.T)

    finite = np.isfinite(x + y + z)
    if not poses.all_finite():
        finite &= poses.finite_per_point()

    # Range is horizontal from the body origin: the sensor sits a metre or so from it, well inside the tolerance.
    r2 = x * x + y * y
    keep = finite & (r2 >= cfg.min_range**2) & (r2 <= cfg.max_range**2)
    n_finite = int(np.count_nonzero(finite))
    n_range = n_finite - int(np.count_nonzero(keep))

    own = _in_own_box(x, y, z, r2, cfg.own_box)
    n_own = int(np.count_nonzero(keep & own))
    if n_own:
        keep &= ~own

    # Usually every return survives the masks above: then the kept returns are the arrays themselves, no copies.
    everything = n_range == 0 and n_own == 0 and n_finite == n
    idx = np.arange(n) if everything else np.flatnonzero(keep)

    def kept(a: np.ndarray) -> np.ndarray:
        return a if everything else np.take(a, idx)

    bx, by = kept(x), kept(y)
    north, east, down, pos_down = _to_world(poses, xyz, bx, by, kept(z), idx)
    # Height above the configured waterline at the body origin, in the level frame of each point's own attitude
    # (world z relative to the body origin: the autopilot's own altitude, GPS or baro, never enters).
    height = cfg.origin_height_above_water - (down - pos_down)
    rings = kept(ring) if ring is not None else None
    horizontal = np.sqrt(r2)
    image = RangeImage.build(point_t, ring, horizontal) if ring is not None and point_t is not None else None
    vertical = alone = None
    if image is not None:
        neighbours_all, vertical_all = image.continuous_and_vertical(
            horizontal,
            (cfg.continuity_abs_tol, cfg.continuity_rel_tol),
            (cfg.vertical_abs_tol, cfg.vertical_rel_tol),
        )
        vertical = kept(vertical_all)
        neighbours = kept(neighbours_all)
        alone = neighbours == 0
    r2_kept = kept(r2)
    not_water = vertical
    if water is not None and image is not None and vertical is not None and cfg.grazing_line_min_run > 0:
        # A low solid met by one beam far out draws a line of returns within the search window of the surface (a
        # pontoon, a quay's foot, a hull's strakes); in the fit it tilts the surface up under itself and hides its
        # own foot beneath it. Far water does not draw lines (_grazing_lines), so lines stay out of the fit.
        reach = cfg.water.max_offset + cfg.water.search_window  # the highest the fit's window ever looks
        far = np.flatnonzero((r2_kept >= cfg.grazing_line_min_range**2) & (height <= reach) & ~vertical)
        if far.size:
            runs = image.ring_runs(idx[far], horizontal[idx[far]], cfg.continuity_abs_tol, cfg.continuity_rel_tol)
            not_water = vertical.copy()
            not_water[far[runs >= cfg.grazing_line_min_run]] = True
    estimate = (
        water.update(bx, by, height, t, rings, not_water, alone, _hull_test(on_hull, north, east))
        if water is not None
        else WaterEstimate(margin=cfg.water.margin_floor)
    )
    sea_returning = not estimate.measured and _sea_returning(height, r2_kept, vertical, cfg)
    if estimate.measured:
        height = height - estimate.floor(bx, by)
    elif water is not None and sea_returning:
        # The sea returns, yet no surface could be fitted to it (rougher than the fit takes, or no fit yet): the
        # calm floor would make its crests obstacles all round the boat. Nothing up to margin_max is a solid until
        # a fit is accepted, and the beams vouch for nothing below it: those bins are unknown, not clear.
        estimate = replace(estimate, margin=cfg.water.margin_max)
    margin = estimate.margin

    in_band = (height >= cfg.min_height) & (height <= cfg.max_height)
    n_height = int(np.count_nonzero(~in_band))
    # At or below the surface plus the sea margin: water (a crest, a trough, a slick), never an obstacle.
    solid = in_band & (height > margin)
    n_water = int(np.count_nonzero(in_band & ~solid))
    n_isolated = n_grazing = 0
    if vertical is not None and cfg.vertical_foot_min_range < cfg.max_range:
        # A face's foot: the laser above or below returned at the same range (config: vertical_foot_min_range).
        # Adjacent lasers, 2 deg apart, lie 0.035 m apart per metre of range, so a wave whose crests stand c above
        # its troughs' depth pairs two of them on one face out to 2 c / tan(2 deg): 24 m for the tests' chop (crests
        # 0.3 m, 3 sigmas 0.41 m), 32 m for one 1.5 times as high, whose faces were paired into obstacles at 20-25 m
        # all round the boat. Unmeasured, the margin stands for the crests.
        crest = cfg.water.margin_sigmas * estimate.spread if estimate.measured else margin
        foot_range = max(cfg.vertical_foot_min_range, 2.0 * crest / _LASER_STEP_TAN)
        foot = in_band & ~solid & vertical & (r2_kept >= foot_range**2)
        n_grazing = int(np.count_nonzero(foot))
        n_water -= n_grazing
        solid |= foot
    # Rain and spray: alone in the range image (no firing beside it returned at its range).
    isolated = grazing_face = short_lines = None
    sparse_sea = None  # (16,) by ring: the lasers whose sea the grazing-line rule judged sparse; None: not judged
    if image is not None and cfg.continuity_min_neighbours > 0:
        need = cfg.continuity_min_neighbours + (r2_kept < cfg.continuity_near_range**2)
        alone = solid & (neighbours < need)
        n_isolated = int(np.count_nonzero(alone))
        solid &= ~alone
        isolated = alone
        if cfg.grazing_face_array_only:
            far_alone = np.flatnonzero(alone & (r2_kept >= cfg.continuity_near_range**2))
            on_line = image.on_ring_line(
                idx[far_alone], horizontal[idx[far_alone]], cfg.continuity_abs_tol, cfg.continuity_rel_tol
            )
            grazing_face = np.zeros(idx.size, dtype=bool)
            grazing_face[far_alone[on_line]] = True
        # Calm water is a mirror: a firing that meets it does not return. So while the water is not returning (no
        # surface measured, and fewer water-like returns than a fit needs), a return within the sea margin in a
        # line of returns at its range is the foot of a solid the beam met just before the water: a RIB at 41 m
        # met by the -1 deg beam 3 cm above its waterline, a quay 80 m off. Once the water does return, a line of
        # water returns is possible and nothing in the margin is trusted.
        # The water's activity is judged close in (_sea_returning), where a rough sea returns the steep beams by the
        # hundred and solids' feet are few. Rain drops and spray above the calm floor are not the water: counted
        # as such, 1,000 drops a revolution made a glassy sea look rough and no foot was kept in rain.
        calm = not estimate.measured and not sea_returning
        if cfg.foot_min_neighbours > 0 and calm:
            rescued = in_band & ~solid & (height > 0.0) & (neighbours >= cfg.foot_min_neighbours)
            n_rescued = int(np.count_nonzero(rescued))
            n_grazing += n_rescued
            n_water -= n_rescued
            solid |= rescued
        elif cfg.grazing_line_min_run > 0 and estimate.measured:  # an unmeasured sea: its lines are not judged
            bins_kept = kept(bins) if bins is not None else bearing_bins(np.column_stack([bx, by]))
            line, short_lines, sparse_sea = _grazing_lines(
                image, idx, horizontal, height, in_band, (estimate, beams), r2_kept, bins_kept, rings, cfg
            )
            line &= ~solid  # a foot on a face is solid already
            short_lines &= ~solid
            n_line = int(np.count_nonzero(line))
            n_grazing += n_line
            n_water -= n_line
            solid |= line

    # Spray suspects: any return near the boat, where a real hull gives dense returns (0.2 deg steps are
    # centimetres apart at a few metres) but bow spray gives lone points in mid-air; and low returns, out to where
    # rain falls dense (continuity_near_range) when the range image judged the rest, everywhere when it did not.
    # Farther out a low return in a line of returns is kept: a quay 54 m off met by one beam gives two or three
    # returns 0.4 m up, which this 3-neighbour ball test dropped.
    low_top = cfg.spray_max_height + margin - cfg.water.margin_floor
    near = r2_kept < cfg.spray_near_range**2
    low_reach = r2_kept < cfg.continuity_near_range**2 if image is not None else True
    low = solid & (near | ((height < low_top) & low_reach))
    spray = np.zeros(idx.size, dtype=bool)
    low_idx = np.flatnonzero(low)
    if low_idx.size:
        # Neighbours among the solid returns within reach of a suspect (a low return next to a hull is hull),
        # counted without itself.
        reach = solid & (
            (height < low_top + cfg.spray_radius) | (r2_kept < (cfg.spray_near_range + cfg.spray_radius) ** 2)
        )
        reach_idx = np.flatnonzero(reach)
        reach_pts = np.column_stack([np.take(north, reach_idx), np.take(east, reach_idx), np.take(down, reach_idx)])
        low_in_reach = np.searchsorted(reach_idx, low_idx)  # low is a subset of reach: each one's place among it
        # The cube block (about 1.5 x spray_radius either way) holds the ball of spray_radius, so its count is an
        # upper bound. Far out that generosity is right: rings are 2 deg apart, so a hull's low edge has few
        # neighbours within 0.5 m at 40 m. Near the boat, where hulls are dense and spray comes in bursts of a few
        # returns, a count just above the minimum is checked exactly (distances to the few points around those few).
        grid = CubeGrid(reach_pts, cfg.spray_radius)
        upper = grid.upper_counts(low_in_reach)
        verdict = upper < cfg.spray_min_neighbours
        unsure = ~verdict & (upper < _EXACT_BELOW * max(cfg.spray_min_neighbours, 1)) & near[low]
        if np.any(unsure):
            verdict[unsure] = grid.exact_counts(low_in_reach[unsure]) < cfg.spray_min_neighbours
        spray[low_idx] = verdict
    n_spray = int(np.count_nonzero(spray))

    good = solid & ~spray
    # Feet of solid lines reach the obstacle array only. Given to the tracker as well they drew quays' clusters out
    # along their feet: held out, fused MOTA 0.798 -> 0.796 (worst scene 0.329 -> 0.226). Returns under the band
    # count as the margin's do: one beam along a hull's waterline 50 m off meets it in the troughs, under a surface
    # the crests' returns lifted, and those firings broke the run that held the hull's solid returns. Held out
    # (random:1001-1050, fused): false-clear bins 853 -> 845, false-obstacle bins 3,801 -> 3,800, tracking unchanged.
    feet = (
        _feet_of_solid_lines(image, idx, horizontal, ~solid & (height <= cfg.max_height), good, r2_kept, cfg)
        if image is not None and cfg.solid_line_min_run > 0
        else np.zeros(idx.size, dtype=bool)
    )
    if grazing_face is not None:
        feet |= grazing_face
    if short_lines is not None:
        feet |= short_lines
    if everything:
        keep = good.copy()
    else:
        keep[idx[~good]] = False
    # Below the calm floor only far out, where one beam meets a hull at its waterline (config: waterline_gate_range).
    low_enough = (height > cfg.water.margin_floor) | (r2_kept >= cfg.waterline_gate_range**2)
    # Within the spray range too, on a face (the laser above or below returned at its range): a buoy 0.6 m tall 6 m
    # off stands mostly under a 0.4 m margin, and only a hull's track, never one return, makes these solid (pipeline:
    # hull_margin_grow_m; the recurrence rule looks 12 m out). There the steep beams meet the crests by the hundred,
    # and a coasting or false track's grown box took them in as obstacles where no solid stood.
    undecided = in_band & ~solid & low_enough
    if vertical is not None:
        undecided &= vertical | (r2_kept >= cfg.spray_near_range**2)
    else:
        undecided &= r2_kept >= cfg.spray_near_range**2
    if image is not None:
        undecided &= neighbours > 0
    n_nonfinite = n - n_finite
    reason = None
    if reasons:  # only for a live view: the range mask again, rather than keeping it on the hot path
        in_range = (r2 >= cfg.min_range**2) & (r2 <= cfg.max_range**2)
        reason = _reasons(n, finite, in_range, idx, in_band, isolated, spray, good)
    if n_nonfinite:
        log.debug("preprocess: %d non-finite returns skipped", n_nonfinite)
    return PreprocessResult(
        points_world=_stack_where(good, north, east, down),
        keep=keep,
        n_nonfinite=n_nonfinite,
        n_range=n_range,
        n_own_boat=n_own,
        n_height=n_height,
        n_spray=n_spray,
        n_water=n_water,
        n_isolated=n_isolated,
        n_grazing=n_grazing,
        water=estimate,
        within_margin_world=_stack_where(undecided, north, east, down),
        within_margin_sparse=(
            sparse_sea[rings[undecided]] if sparse_sea is not None and rings is not None else np.ones(0, dtype=bool)
        ),
        feet_world=_stack_where(feet, north, east, down),
        reason=reason,
    )


def _grazing_lines(
    image: RangeImage,
    idx: np.ndarray,
    horizontal: np.ndarray,
    height: np.ndarray,
    in_band: np.ndarray,
    sea: tuple[WaterEstimate, BeamGeometry | None],
    r2_kept: np.ndarray,
    bins: np.ndarray,
    rings: np.ndarray,
    cfg: PreprocessConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K,) each over the kept returns: those within the sea margin that are a solid's face met at grazing
    incidence, and those in runs of grazing_line_array_run firings or more, short of grazing_line_min_run, on
    lasers whose sea is sparser still (grazing_line_array_max_sporadic), for the obstacle array only; and (16,) by
    ring, the lasers whose sea is sparse (below).

    A returning sea still draws no lines far out: beyond grazing_line_min_range its returns come a firing or two at
    a time along a ring, while the strakes of a low hull at 20-60 m under the crests' margin, met by one beam,
    return a run of firings at one range. At any height within the margin: a solid's waterline met by one beam lies
    at or below the calm floor, often below the fitted surface (which the crests' returns lift). Held to the part
    above the floor, on the tuning scenes in sea state 3 two thirds of the false-clear bins were solids returned
    only there. But only on a laser whose sea is sparse: at most grazing_line_max_sporadic of its firings that met
    the water beyond grazing_line_min_range returned in the margin outside a run (the sea's own rate: solids come in
    runs, so a quay along the beam does not raise it), and at most grazing_line_max_fill of its firings that met the
    water anywhere beyond the fit's minimum range returned in the margin at all (a sea returning firing after firing
    draws its returns into runs along the crests, which the first measure then misses). The fill is judged over the
    laser's whole water, near and far: where a sea returns every firing, a laser coming down to it at 18 m returns
    mostly short of 20 m, and the few firings reaching a trough beyond draw lines there; judged by its firings
    beyond 20 m alone, that laser looked sparse. A laser's fill is never judged above a steeper laser's that met
    the water as widely (_fill_below): the sea returns less to a flatter beam, so the excess is its solids.

    The firings that met the water are counted from the beams' geometry (``sea``: the water estimate and where the
    beams pointed): those in the bins where the laser came down through the sea margin within the range judged and
    the revolution's farthest return. Counting only the bins that returned something in the margin judged a laser
    by its solids: a laser that met the water in range only here and there but ran along hulls' strakes had its
    bins full, and none of its lines was trusted. Without the geometry those bins are all there is to count. For
    the sporadic rate a bin counts where the middle of the laser's passage through the margin (about where it
    meets the mean surface) lies beyond grazing_line_min_range, not where its far end (a trough as deep as the
    margin is high) does: under a boat listing 5 deg, a laser meeting the mean water at 19-20 m reached 20 m only in
    the troughs of 4 bins, yet its far end lay beyond 20 m in 15; its sea's 13 lone returns there were counted
    against all 15 bins' firings (a rate of 0.035, "sparse"), and five returns in a row in a trough were a line.
    """
    wet = in_band & (height <= sea[0].margin)
    far = wet & (r2_kept >= cfg.grazing_line_min_range**2)
    far_idx = np.flatnonzero(far)
    if far_idx.size == 0:
        return far, far.copy(), np.ones(RINGS, dtype=bool)
    firings_per_bin = image.n_sequences / N_BINS
    reach = float(np.sqrt(r2_kept.max()))
    far_rings = rings[far_idx].astype(np.int64)
    met = _cells(far_rings, bins[far_idx])
    wet_idx = np.flatnonzero(wet & (r2_kept >= cfg.water.fit_min_range**2))
    wet_rings = rings[wet_idx].astype(np.int64)
    met_wet = _cells(wet_rings, bins[wet_idx])
    if sea[1] is not None:
        lo, hi = _laser_in_sea_margin(sea[0], sea[1], reach, cfg)
        with np.errstate(invalid="ignore"):  # inf + -inf where the laser never comes down: False, as it should
            met |= (hi >= lo) & (0.5 * (lo + hi) >= cfg.grazing_line_min_range)
        met_wet |= hi >= np.maximum(lo, cfg.water.fit_min_range)
    runs = image.ring_runs(idx[far_idx], horizontal[idx[far_idx]], cfg.continuity_abs_tol, cfg.continuity_rel_tol)
    alone = runs < cfg.grazing_line_min_run
    # Of a cell's firings, only those whose water lay beyond the range judged count as met there. Where the laser
    # comes down through the margin across that range, its troughs alone reach beyond it: the share of the cell's
    # water returns lying beyond is that of its firings. Counted whole, such cells made a sea returning 30 % of
    # its firings look sparse, and five trough returns in a row were a line (a listing boat over a travelling chop,
    # tests/test_sea_state.py).
    n_wet = _cell_counts(wet_rings, bins[wet_idx]).astype(float)
    n_far = _cell_counts(far_rings, bins[far_idx])
    met_share = np.where(n_wet > 0, np.minimum(n_far / np.maximum(n_wet, 1.0), 1.0), met)
    met_firings = np.maximum(met_share.sum(axis=1) * firings_per_bin, 1.0)
    sporadic = np.bincount(far_rings[alone], minlength=RINGS) / met_firings
    wet_bins = np.count_nonzero(met_wet, axis=1)
    wet_firings = np.maximum(wet_bins * firings_per_bin, 1.0)
    fill = _fill_below(np.bincount(wet_rings, minlength=RINGS) / wet_firings, wet_bins)
    sporadic_sea = (sporadic <= cfg.grazing_line_max_sporadic) & (fill <= cfg.grazing_line_max_fill)
    # A sea returning a share p of a laser's firings draws runs of L returns by chance about n p**L times in n
    # firings: at p = 0.1 (sparse by the rates above) a trough 23 m off gave a run of 5 once in 30 revolutions
    # (tests/test_sea_state.py). The run a line needs grows until chance gives one in 1 / grazing_line_chance
    # revolutions of that laser.
    with np.errstate(divide="ignore", invalid="ignore"):
        chance_run = np.ceil(np.log(cfg.grazing_line_chance / met_firings) / np.log(sporadic))
    need = np.where(
        (sporadic > 0) & (sporadic < 1), np.maximum(chance_run, cfg.grazing_line_min_run), cfg.grazing_line_min_run
    )
    line = far.copy()
    line[far_idx[(runs < need[far_rings]) | ~sporadic_sea[far_rings]]] = False
    short = np.zeros_like(far)
    if 0 < cfg.grazing_line_array_run < cfg.grazing_line_min_run:
        sparser = sporadic_sea & (sporadic <= cfg.grazing_line_array_max_sporadic)
        short[far_idx[alone & (runs >= cfg.grazing_line_array_run) & sparser[far_rings]]] = True
    return line, short, sporadic_sea


def _fill_below(fill: np.ndarray, wet_bins: np.ndarray) -> np.ndarray:
    """(16,) each laser's fill, or the smallest fill of a steeper laser (a lower ring) that met the water in at least
    as many bins, where that is smaller.

    The sea returns less the more flatly a beam grazes it, so a laser meeting the water 2 deg flatter than the one
    below it cannot return it more densely: a fill above the steeper lasers' is solids along it. The highest laser
    that comes down to the water at all meets it only in the bins the boat's heel tips it into, far out, where a
    quay or a hull often stands; its foot in the margin, a run along the whole bin, filled that laser's few water
    bins past grazing_line_max_fill while the lasers below returned a tenth of their firings (tuning seeds 10 and
    12, sea state 3: quays 25-70 m off met by the -1 or +1 deg laser alone, unknown in bin after bin).
    """
    lower = np.tri(RINGS, RINGS, -1, dtype=bool)  # [r, r']: r' is a steeper laser than r
    support = wet_bins[None, :] >= wet_bins[:, None]
    below = np.where(lower & support, fill[None, :], np.inf).min(axis=1)
    return np.minimum(fill, below)


def _feet_of_solid_lines(
    image: RangeImage,
    idx: np.ndarray,
    horizontal: np.ndarray,
    water: np.ndarray,
    good: np.ndarray,
    r2_kept: np.ndarray,
    cfg: PreprocessConfig,
) -> np.ndarray:
    """(K,) over the kept returns: the ``water`` ones beyond grazing_line_min_range that lie in a run along their
    laser (at least solid_line_min_run firings at one range) holding a ``good`` one."""
    far = r2_kept >= cfg.grazing_line_min_range**2
    members = np.flatnonzero(far & (water | good))
    foot = np.zeros(idx.size, dtype=bool)
    if members.size == 0 or not np.any(water[members]):
        return foot
    run_id, length = image.ring_run_ids(
        idx[members], horizontal[idx[members]], cfg.continuity_abs_tol, cfg.continuity_rel_tol
    )
    holds_solid = np.bincount(run_id, weights=good[members], minlength=length.size) > 0
    foot[members] = water[members] & holds_solid[run_id] & (length[run_id] >= cfg.solid_line_min_run)
    return foot


def _hull_test(
    on_hull: Callable[[np.ndarray], np.ndarray] | None, north: np.ndarray, east: np.ndarray
) -> Callable[[np.ndarray], np.ndarray] | None:
    """``on_hull`` asked by the kept returns' indices (the water fit's terms) rather than by world place."""
    if on_hull is None:
        return None
    return lambda i: on_hull(np.column_stack([np.take(north, i), np.take(east, i)]))


def _cells(ring: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """(16, 72) bool by ring and bin: some of these returns (their laser and obstacle-array bin) lie there."""
    return _cell_counts(ring, bins) > 0


def _cell_counts(ring: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """(16, 72) by ring and bin: how many of these returns (their laser and obstacle-array bin) lie there."""
    return np.bincount(ring * N_BINS + bins, minlength=RINGS * N_BINS).reshape(RINGS, N_BINS)


def _laser_in_sea_margin(
    water: WaterEstimate, beams: BeamGeometry, reach: float, cfg: PreprocessConfig
) -> tuple[np.ndarray, np.ndarray]:
    """(16, 72) each, by ring and bin: the horizontal ranges (m) between which the laser, at the bin's centre
    bearing, comes down through the sea margin (as deep under the surface as the margin is above it: a trough),
    capped at ``reach``; start > end where it never does."""
    elevation, sensor_height = beams.over_surface(water, cfg.origin_height_above_water)
    lo, hi = band_intervals(elevation[BIN_CENTRES], sensor_height[BIN_CENTRES], -water.margin, water.margin, reach)
    return lo[:, RING_COLUMNS].T, hi[:, RING_COLUMNS].T


def _sea_returning(height: np.ndarray, r2: np.ndarray, vertical: np.ndarray | None, cfg: PreprocessConfig) -> bool:
    """At least calm_max_near_returns returns at or below the calm floor (and above min_height) within
    calm_near_range, off any vertical face: with no surface fitted, the water is returning."""
    low = (r2 < cfg.calm_near_range**2) & (height <= cfg.water.margin_floor) & (height >= cfg.min_height)
    if vertical is not None:
        low &= ~vertical
    return int(np.count_nonzero(low)) >= cfg.calm_max_near_returns


def _in_own_box(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, r2: np.ndarray, box: tuple[float, float, float, float, float, float]
) -> np.ndarray:
    """(N,) bool: the return lies in the own boat's box. Only returns within the box's corner radius can (squares
    and sums round monotonically, so r2 <= the corner's r2 for every point inside), and those are a few: the six
    comparisons run on them, not on the revolution."""
    x0, x1, y0, y1, z0, z1 = box
    mx, my = max(abs(x0), abs(x1)), max(abs(y0), abs(y1))
    own = np.zeros(x.shape[0], dtype=bool)
    near = np.flatnonzero(r2 <= mx * mx + my * my)
    if near.size:
        nx, ny, nz = x[near], y[near], z[near]
        own[near] = (nx >= x0) & (nx <= x1) & (ny >= y0) & (ny <= y1) & (nz >= z0) & (nz <= z1)
    return own


def _to_world(
    poses: PoseTable, xyz: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, idx: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """World (north, east, down) columns of the kept returns ``idx`` (body columns ``x``, ``y``, ``z``) and the
    body origin's down coordinate at each."""
    if poses.position.shape[0] == 1:  # one pose for all: the rotation as one matrix product, as body_to_world does
        world, pos_down = poses.body_to_world(np.take(xyz, idx, axis=0), idx)
        return world[:, 0], world[:, 1], world[:, 2], pos_down
    return poses.columns_to_world(x, y, z, idx)


def _stack_where(mask: np.ndarray, north: np.ndarray, east: np.ndarray, down: np.ndarray) -> np.ndarray:
    """(M, 3) world NED of the returns where ``mask``."""
    return np.column_stack([np.compress(mask, north), np.compress(mask, east), np.compress(mask, down)])


def _reasons(
    n: int,
    finite: np.ndarray,
    in_range: np.ndarray,
    idx: np.ndarray,
    in_band: np.ndarray,
    isolated: np.ndarray | None,
    spray: np.ndarray,
    good: np.ndarray,
) -> np.ndarray:
    """Each point's code from the masks the rules left, in the order the counts were taken (a point counted under
    one rule is never counted again), so that np.bincount(reason) gives PreprocessResult.counts() (as long as
    foot_min_neighbours exceeds the isolation test's need, as shipped: a rescued foot is then never also isolated)."""
    reason = np.full(n, OWN_BOAT, dtype=np.int8)  # finite and in range but not among idx: the own-boat box
    reason[~in_range] = RANGE
    reason[~finite] = NONFINITE
    sub = np.full(idx.size, WATER, dtype=np.int8)  # in the height band, yet at or below the sea margin
    sub[~in_band] = HEIGHT
    if isolated is not None:
        sub[isolated] = ISOLATED
    sub[spray] = SPRAY
    sub[good] = KEPT  # a foot rescued from the margin (n_grazing) is kept, not water
    reason[idx] = sub
    return reason
