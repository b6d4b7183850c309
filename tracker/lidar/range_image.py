"""One revolution as the VLP-16 fired it: a (firing sequence x laser) image of horizontal ranges.

Two questions about a return are answered by its neighbours in that image, not by a search in space:

* Is it part of a surface? A hull, a quay or a buoy returns the neighbouring firings (0.2 deg along the ring, 2 deg
  to the next laser) at nearly the same range; a rain drop or a spray droplet is alone: the firings beside it pass
  it by. (``continuous_and_vertical``)
* Is it on a vertical face? A wall or a hull side returns the lasers above and below at the same horizontal range;
  the sea surface returns the next laser up much farther out, or not at all. (``vertical``)

A firing's sequence comes from its time: the 16 lasers fire 2.304 us apart within a 55.296 us sequence (vlp16.md
§4), so (t - laser offset) is the same for all 16 and steps by one sequence per 0.2 deg. Work is a few shifted
comparisons of a (sequences x 16) array, about 29k cells a revolution, whatever the points are.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

SEQUENCE_S = 55.296e-6
FIRING_S = 2.304e-6
RINGS = 16
# VLP-16 laser id of each ring (ring 0 = lowest beam, -15 deg): lasers alternate -15, +1, -13, +3, ...
LASER_OF_RING = np.array([0, 2, 4, 6, 8, 10, 12, 14, 1, 3, 5, 7, 9, 11, 13, 15], dtype=np.int64)
MAX_SEQUENCES = 40_000  # 2.2 s of firings: a revolution with a wilder time spread gets no image
CONTINUITY_OFFSETS = [(ds, dr) for ds in (-1, 0, 1) for dr in (-1, 0, 1) if (ds, dr) != (0, 0)]
VERTICAL_OFFSETS = [(ds, dr) for ds in (-1, 0, 1) for dr in (-2, -1, 1, 2)]
# A per-return gather of its ~20 neighbour cells costs about what comparing 8 cells of the whole image does (measured:
# equal at ~4.5k returns a revolution); with fewer returns (calm water returns almost nothing) it is the cheaper.
_GATHER_BELOW = 8


def _cell_counts(image: np.ndarray, rules: list[tuple[list[tuple[int, int]], float, float]]) -> list[np.ndarray]:
    """Per rule (offsets, abs_tol, rel_tol): (cells,) int8, each cell of the flat padded image's neighbours at the
    rule's offsets within abs_tol + rel_tol x its range (meaningful for the centre cells only).

    Everything runs on the flat image: a neighbour at (ds, dr) is ``ds * width + dr`` cells further on, so every
    step is one pass over contiguous memory (2-D slices of a 20-column image cost three times as much). Each
    unordered pair of cells is differenced once, for every rule and both directions: the difference towards
    -shift is the one towards +shift read at the neighbour (|a - b| == |b - a| exactly in floating point); one
    difference array at a time keeps the work in cache. The padding keeps every centre cell's neighbours within
    its own row."""
    flat = image.ravel()
    width = image.shape[1]
    with np.errstate(invalid="ignore"):
        tols = [abs_tol + rel_tol * flat for _, abs_tol, rel_tol in rules]
        counts = [np.zeros(flat.size, dtype=np.int8) for _ in rules]
        scratch = np.empty(flat.size, dtype=bool)
        shifts = [[ds * width + dr for ds, dr in offsets] for offsets, _, _ in rules]
        for shift in sorted({abs(k) for ks in shifts for k in ks}):
            d = np.subtract(flat[shift:], flat[:-shift])
            np.abs(d, out=d)
            n = d.size
            near = scratch[:n]
            for ks, tol, count in zip(shifts, tols, counts, strict=True):
                if shift in ks:  # towards +shift: the cell's own difference
                    np.less_equal(d, tol[:n], out=near)
                    count[:n] += near.view(np.int8)
                if -shift in ks:  # towards -shift: the neighbour's difference
                    np.less_equal(d, tol[-n:], out=near)
                    count[-n:] += near.view(np.int8)
    return counts


@dataclass(frozen=True)
class RangeImage:
    seq: np.ndarray  # (N,) firing sequence of each return, 0-based
    ring: np.ndarray  # (N,) int
    image: np.ndarray  # (S + 2, RINGS + 4) horizontal range, m; NaN = no return; one cell of padding on each side

    @classmethod
    def build(cls, t: np.ndarray, ring: np.ndarray, horizontal_range: np.ndarray) -> RangeImage | None:
        """None when the times or rings cannot place the returns (non-finite times, a ring beyond 15, a spread
        longer than MAX_SEQUENCES): then the rules that need it are not applied, and the caller says so."""
        t = np.asarray(t, dtype=float)
        ring_i = np.asarray(ring, dtype=np.int64)
        if t.size == 0 or not np.isfinite(t).all() or ring_i.min() < 0 or ring_i.max() >= RINGS:
            return None
        start = t - np.take(LASER_OF_RING, ring_i) * FIRING_S
        seq = np.rint((start - start.min()) * (1.0 / SEQUENCE_S)).astype(np.int64)
        n_seq = int(seq.max()) + 1
        if n_seq > MAX_SEQUENCES:
            return None
        image = np.full((n_seq + 2, RINGS + 4), np.nan)
        out = cls(seq, ring_i, image)
        image.ravel()[out._cell] = horizontal_range
        return out

    @property
    def n_sequences(self) -> int:
        """Firing sequences the revolution spans (the image's rows less their padding)."""
        return self.image.shape[0] - 2

    @cached_property
    def _cell(self) -> np.ndarray:
        """(N,) each return's cell in the flat image (a flat index costs a fraction of a 2-D one)."""
        return (self.seq + 1) * self.image.shape[1] + (self.ring + 2)

    def _sparse(self) -> bool:
        return self.seq.size * _GATHER_BELOW < self.image.size

    def _count(self, r: np.ndarray, offsets: list[tuple[int, int]], abs_tol: float, rel_tol: float) -> np.ndarray:
        """For each return: how many cells at (sequence, ring) ``offsets`` hold a range within abs_tol + rel_tol x
        its own."""
        return self._counts(r, [(offsets, abs_tol, rel_tol)])[0]

    def _counts(self, r: np.ndarray, rules: list[tuple[list[tuple[int, int]], float, float]]) -> list[np.ndarray]:
        """:meth:`_count` for each (offsets, abs_tol, rel_tol) of ``rules``. The comparison runs once per offset
        over the whole image (about 36k cells, no index arrays), then each return reads its own cell: a per-return
        gather of (N, offsets) cells cost 4 ms a revolution at 25k returns. The padding (one row, two columns each
        side) keeps every offset of at most one sequence and two rings inside the image. A return that shares its
        cell with another (dual returns, or two firings rounded into one sequence) is not the cell's range and is
        counted on its own. A sparse revolution gathers each return's neighbours instead (the same comparisons,
        fewer cells)."""
        if self._sparse():
            return [self._count_gather(r, self.seq, self.ring, *rule) for rule in rules]
        cell = self._cell
        shared = np.flatnonzero(np.take(self.image.ravel(), cell) != r)
        out = []
        for (offsets, abs_tol, rel_tol), per_cell in zip(rules, _cell_counts(self.image, rules), strict=True):
            counts = np.take(per_cell, cell).astype(np.int64)
            if shared.size:
                counts[shared] = self._count_gather(
                    r[shared], self.seq[shared], self.ring[shared], offsets, abs_tol, rel_tol
                )
            out.append(counts)
        return out

    def _count_gather(
        self,
        r: np.ndarray,
        seq: np.ndarray,
        ring: np.ndarray,
        offsets: list[tuple[int, int]],
        abs_tol: float,
        rel_tol: float,
    ) -> np.ndarray:
        ds = np.array([o[0] for o in offsets], dtype=np.int64)
        dr = np.array([o[1] for o in offsets], dtype=np.int64)
        width = self.image.shape[1]
        flat = (seq + 1)[:, None] * width + (ring + 2)[:, None] + (ds * width + dr)
        other = np.take(self.image.ravel(), flat)
        with np.errstate(invalid="ignore"):
            near = np.abs(other - r[:, None]) <= (abs_tol + rel_tol * r)[:, None]
        return np.count_nonzero(near, axis=1)

    def vertical(self, r: np.ndarray, abs_tol: float, rel_tol: float) -> np.ndarray:
        """(N,) bool: a laser one or two rings above or below, within one sequence, returned at the same horizontal
        range (within abs_tol + rel_tol * r): the return lies on a vertical face."""
        return self._count(r, VERTICAL_OFFSETS, abs_tol, rel_tol) > 0

    def on_ring_line(self, members: np.ndarray, r: np.ndarray, abs_tol: float, rel_tol: float) -> np.ndarray:
        """(M,) bool for each of the returns ``members`` (ranges ``r``): it is one of three firings in a row on its
        ring (it and the two before, after, or either side) that returned on a straight line in range (the second
        difference within abs_tol + rel_tol * the middle one's range). A flat face met at grazing incidence steps
        its range by metres between firings, so no neighbour lies at its range, yet its firings fall on a line;
        drops beside a drop do not."""
        width = self.image.shape[1]
        cell = (self.seq[members] + 1) * width + (self.ring[members] + 2)
        flat = self.image.ravel()
        # beyond the image's ends: its padding rows (NaN)
        around = {k: np.take(flat, cell + k * width, mode="clip") for k in (-2, -1, 1, 2)}
        around[0] = r
        line = np.zeros(len(members), dtype=bool)
        with np.errstate(invalid="ignore"):
            for lo in (-2, -1, 0):
                a, mid, b = around[lo], around[lo + 1], around[lo + 2]
                line |= np.abs(a + b - 2.0 * mid) <= abs_tol + rel_tol * mid
        return line

    def ring_runs(self, members: np.ndarray, r: np.ndarray, abs_tol: float, rel_tol: float) -> np.ndarray:
        """(M,) for each of the returns ``members`` (indices of this image's returns, ranges ``r``): the length of
        the run it belongs to among the members: consecutive firings of its laser each within abs_tol + rel_tol * r
        of the one before (1: alone on its ring). A few (ring x sequence) array passes, whatever M is."""
        run_id, length = self.ring_run_ids(members, r, abs_tol, rel_tol)
        return length[run_id]

    def ring_run_ids(
        self, members: np.ndarray, r: np.ndarray, abs_tol: float, rel_tol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The runs of :meth:`ring_runs`: (M,) each member's run id, and (runs,) each run's length."""
        seq, ring = self.seq[members], self.ring[members]
        n_seq = self.n_sequences
        runs = np.full((RINGS, n_seq), np.nan)  # ring-major: a ring's firings are contiguous once flattened
        runs[ring, seq] = r
        flat = runs.ravel()
        present = np.isfinite(flat)
        linked = np.zeros(flat.size, dtype=bool)
        with np.errstate(invalid="ignore"):
            linked[1:] = np.abs(flat[1:] - flat[:-1]) <= abs_tol + rel_tol * flat[1:]
        linked[::n_seq] = False  # a ring's first firing does not continue the ring below's last one
        starts = present & ~linked
        run_id = np.cumsum(starts) - 1
        length = np.bincount(run_id[present], minlength=int(starts.sum()))
        return run_id[ring * n_seq + seq], length

    def continuous_and_vertical(
        self, r: np.ndarray, continuity_tol: tuple[float, float], vertical_tol: tuple[float, float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """(N,) neighbours among the 8 around each return (the firings beside it on its ring, and the lasers above
        and below within one sequence) at a range within abs + rel * r of its own, and :meth:`vertical`, each with
        its (abs, rel) tolerance, in one go: the two share six of their offsets, and each difference between
        neighbouring cells is taken once for both."""
        neighbours, vertical = self._counts(
            r, [(CONTINUITY_OFFSETS, *continuity_tol), (VERTICAL_OFFSETS, *vertical_tol)]
        )
        return neighbours, vertical > 0
