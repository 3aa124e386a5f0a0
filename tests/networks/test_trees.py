"""Street trees: kinds, lobed crowns, limbs forking into the crown, classes, seeded by position."""

from collections import Counter

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Polygon

from networks.classes import SemanticClass
from networks.trees import KINDS, street_tree, tree_kind


def _closed_outward(v: np.ndarray, t: np.ndarray) -> tuple[bool, float]:
    edges = Counter(tuple(sorted(e)) for tri in t for e in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])))
    centre = v[t].reshape(-1, 3).mean(axis=0)
    a, b, c = v[t[:, 0]] - centre, v[t[:, 1]] - centre, v[t[:, 2]] - centre
    return set(edges.values()) == {2}, float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _inside(point: np.ndarray, v: np.ndarray, t: np.ndarray) -> bool:
    """Whether ``point`` lies inside the closed surface (a ray along a skew direction crosses it an
    odd number of times)."""
    d = np.array([0.31, 0.17, 0.93])
    tri = v[t]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    s = point - tri[:, 0]
    u = np.einsum("ij,ij->i", s, p) / np.where(ok, det, 1.0)
    q = np.cross(s, e1)
    w = (q @ d) / np.where(ok, det, 1.0)
    dist = np.einsum("ij,ij->i", e2, q) / np.where(ok, det, 1.0)
    return int((ok & (u >= 0) & (w >= 0) & (u + w <= 1) & (dist > 0)).sum()) % 2 == 1


@settings(max_examples=40, deadline=None)
@given(st.floats(-500.0, 500.0), st.floats(-500.0, 500.0), st.sampled_from(KINDS), st.integers(0, 3))
def test_every_tree_is_a_closed_crown_over_a_trunk_whose_limbs_end_inside_it(x, y, kind, seed):
    tree = street_tree(x, y, 0.1, seed, kind=kind)
    v, t, cls = tree.vertices_m.astype(np.float64), tree.triangles, tree.triangle_class
    assert set(cls.tolist()) == {SemanticClass.VEGETATION, SemanticClass.TRUNK}
    crown = t[cls == SemanticClass.VEGETATION]
    closed, volume = _closed_outward(v, crown)
    assert closed and volume > 0  # one closed crown, faces outwards
    wood = t[cls == SemanticClass.TRUNK]
    foot = v[wood].reshape(-1, 3)
    assert np.isclose(foot[:, 2].min(), 0.1, atol=1e-4)  # the trunk stands on the ground
    assert np.hypot(foot[:, 0] - x, foot[:, 1] - y).max() < 1.5
    crown_low = v[crown].reshape(-1, 3)[:, 2].min()
    tops = v[np.unique(wood)]
    tips = tops[tops[:, 2] > crown_low + 0.2]
    assert len(tips) >= 4 and all(_inside(p, v, crown) for p in tips)  # the wood's ends lie inside the crown
    clear = foot[foot[:, 2] < crown_low - 0.05]  # wood below the crown: seen (trunk and forking limbs)
    assert len(clear) >= 6 and crown_low > 1.5


def test_broadleaf_and_columnar_crowns_are_lobed_seen_from_above():
    """The crown's outline seen from above: its distance from the trunk around it varies by more
    than 40 % of its mean for the middle tree (a smooth ellipsoid's with bumps of a few per cent:
    about 25 %)."""
    for kind in ("broadleaf", "columnar"):
        spread = []
        for i in range(15):
            x, y = 10.0 + 7.3 * i, 5.0
            tree = street_tree(x, y, 0.0, 0, kind=kind)
            tri = tree.vertices_m[tree.triangles[tree.triangle_class == SemanticClass.VEGETATION]].astype(np.float64)
            outline = shapely.unary_union([p for p in (Polygon(k[:, :2]) for k in tri) if p.area > 1e-9]).exterior
            reach = []
            for a in np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False):
                hit = LineString([(x, y), (x + 20.0 * np.cos(a), y + 20.0 * np.sin(a))]).intersection(outline)
                pts = np.asarray([(g.x, g.y) for g in getattr(hit, "geoms", [hit])])
                reach.append(np.hypot(pts[:, 0] - x, pts[:, 1] - y).max())
            r = np.asarray(reach)
            spread.append((r.max() - r.min()) / r.mean())
        assert np.median(spread) > 0.4, (kind, spread)


def test_the_same_place_and_seed_give_the_same_tree_and_other_places_other_trees():
    a = street_tree(12.34, -56.78, 0.0, 3)
    b = street_tree(12.34, -56.78, 0.0, 3)
    assert np.array_equal(a.vertices_m, b.vertices_m) and np.array_equal(a.triangles, b.triangles)
    c = street_tree(12.34, -56.78 + 9.0, 0.0, 3, kind=tree_kind(12.34, -56.78, 3))
    d = street_tree(12.34, -56.78, 0.0, 4, kind=tree_kind(12.34, -56.78, 3))
    for other in (c, d):
        assert other.vertices_m.shape != a.vertices_m.shape or not np.allclose(
            other.vertices_m - other.vertices_m.mean(0), a.vertices_m - a.vertices_m.mean(0), atol=0.05
        )


def test_kinds_come_in_their_shares_and_conifers_only_where_they_fit():
    kinds = Counter(tree_kind(7.1 * i, -3.3 * i, 0) for i in range(600))
    assert 0.5 < kinds["broadleaf"] / 600 < 0.7 and 0.18 < kinds["columnar"] / 600 < 0.32
    assert 0.08 < kinds["conifer"] / 600 < 0.22
    assert "conifer" not in {tree_kind(7.1 * i, -3.3 * i, 0, conifer_fits=False) for i in range(600)}


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_has_its_shape(kind):
    sizes = []
    for i in range(10):
        tree = street_tree(3.0 * i, 1.0, 0.0, 0, kind=kind)
        v = tree.vertices_m[tree.triangles[tree.triangle_class == SemanticClass.VEGETATION]].reshape(-1, 3)
        low, high = v.min(axis=0), v.max(axis=0)
        sizes.append((high[2] - low[2]) / max(high[0] - low[0], high[1] - low[1]))
    ratio = float(np.median(sizes))
    assert {"broadleaf": 0.6 < ratio < 1.2, "columnar": ratio > 1.7, "conifer": ratio > 1.3}[kind], ratio
