"""HOTA (Luiten et al., IJCV 2021), computed here rather than through TrackEval.

TrackEval 1.3.0 installs and runs with numpy 2, but it pulls in OpenCV and pycocotools for this one function. This
is the same algorithm as its ``trackeval.metrics.HOTA`` (tests/test_evaluation_hota.py checks the two agree when
TrackEval is installed): per alpha in 0.05, 0.10, ..., 0.95, detections match by a Hungarian assignment on
similarity weighted by the global alignment of the two ids, a match counts when its similarity is at least alpha,
HOTA_alpha = sqrt(DetA * AssA), and HOTA is the mean over the alphas.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

ALPHAS = np.arange(0.05, 0.99, 0.05)  # TrackEval's 19 thresholds
_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class HotaScores:
    hota: float
    det_a: float
    ass_a: float
    loc_a: float

    def to_dict(self) -> dict[str, float]:
        return {"hota": self.hota, "deta": self.det_a, "assa": self.ass_a, "loca": self.loc_a}


def hota(
    gt_ids: Sequence[np.ndarray], tracker_ids: Sequence[np.ndarray], similarity: Sequence[np.ndarray]
) -> HotaScores:
    """HOTA over a sequence: per frame the truth ids (G,), tracker ids (T,) and a (G, T) similarity in [0, 1]."""
    g_all = np.unique(np.concatenate([np.asarray(g, np.int64) for g in gt_ids] or [np.zeros(0, np.int64)]))
    t_all = np.unique(np.concatenate([np.asarray(t, np.int64) for t in tracker_ids] or [np.zeros(0, np.int64)]))
    gts = [np.searchsorted(g_all, np.asarray(g, np.int64)) for g in gt_ids]
    trs = [np.searchsorted(t_all, np.asarray(t, np.int64)) for t in tracker_ids]
    n_gt_dets = sum(g.size for g in gts)
    n_tr_dets = sum(t.size for t in trs)
    if n_gt_dets == 0 or n_tr_dets == 0:
        return HotaScores(0.0, 0.0, 0.0, 1.0)

    # global association: similarity-weighted "potential matches" between each pair of ids over the sequence
    potential = np.zeros((g_all.size, t_all.size))
    gt_count = np.zeros((g_all.size, 1))
    tr_count = np.zeros((1, t_all.size))
    for g, t, s in zip(gts, trs, similarity, strict=True):
        s = np.asarray(s, float).reshape(g.size, t.size)
        denom = s.sum(0)[None, :] + s.sum(1)[:, None] - s
        s_iou = np.zeros_like(s)
        ok = denom > _EPS
        s_iou[ok] = s[ok] / denom[ok]
        potential[g[:, None], t[None, :]] += s_iou
        gt_count[g] += 1
        tr_count[0, t] += 1
    alignment = potential / (gt_count + tr_count - potential)

    tp = np.zeros(ALPHAS.size)
    fn = np.zeros(ALPHAS.size)
    fp = np.zeros(ALPHAS.size)
    loc = np.zeros(ALPHAS.size)
    matches = np.zeros((ALPHAS.size, g_all.size, t_all.size))
    for g, t, s in zip(gts, trs, similarity, strict=True):
        if g.size == 0 or t.size == 0:
            fp += t.size
            fn += g.size
            continue
        s = np.asarray(s, float).reshape(g.size, t.size)
        rows, cols = linear_sum_assignment(-(alignment[g[:, None], t[None, :]] * s))
        matched_sim = s[rows, cols]
        ok = matched_sim[None, :] >= ALPHAS[:, None] - _EPS  # (A, M)
        n = ok.sum(axis=1)
        tp += n
        fn += g.size - n
        fp += t.size - n
        loc += np.where(ok, matched_sim[None, :], 0.0).sum(axis=1)
        a_idx, m_idx = np.nonzero(ok)
        np.add.at(matches, (a_idx, g[rows[m_idx]], t[cols[m_idx]]), 1)

    ass_a = np.sum(matches * (matches / np.maximum(1, gt_count + tr_count - matches)), axis=(1, 2)) / np.maximum(1, tp)
    det_a = tp / np.maximum(1, tp + fn + fp)
    loc_a = np.maximum(1e-10, loc) / np.maximum(1e-10, tp)
    h = np.sqrt(det_a * ass_a)
    return HotaScores(float(h.mean()), float(det_a.mean()), float(ass_a.mean()), float(loc_a.mean()))
