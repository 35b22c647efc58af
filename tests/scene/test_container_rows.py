"""``Scene.from_polylines`` (the one builder of container rows, vectorised across guides) against the
per-segment loop it replaced, written out here as the prediction: one guide at a time, one segment at a time,
scalar parallel transport and bisectors. Generators and grooms both build through ``from_polylines``, so this
holds every scene's frames, joint planes, radii and guide parameters."""

from __future__ import annotations

import numpy as np
import pytest

from app.scene.containers import MAX_GUIDES, SEGMENT_FLOATS, Scene, container_rows, orthonormal_x


def _rotate_minimally(v: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    c = float(np.dot(a, b))
    axis = np.cross(a, b)
    s = float(np.linalg.norm(axis))
    if s < 1e-12:
        if c > 0:
            return v
        axis = np.cross(a, v)
        n = np.linalg.norm(axis)
        axis = axis / n if n > 0 else orthonormal_x(a[None])[0]
        return 2 * np.dot(v, axis) * axis - v
    axis /= s
    return v * c + np.cross(axis, v) * s + axis * np.dot(axis, v) * (1 - c)


def _bisector(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    n = a + b
    length = np.linalg.norm(n)
    return a if length < 1e-9 else n / length


def rows_one_by_one(polylines, radii, taper: float, origin: np.ndarray) -> np.ndarray:
    """The container rows, segment after segment (float64)."""
    radii = np.broadcast_to(np.asarray(radii, np.float64), (len(polylines),))
    rows = []
    for g, pts in enumerate(np.asarray(q, np.float64) for q in polylines):
        seglen = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        pts = pts[np.concatenate([[True], seglen > 0])]
        if len(pts) < 2:
            continue
        seglen = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        v = np.concatenate([[0.0], np.cumsum(seglen)]) / seglen.sum()
        r = radii[g] * (1.0 - taper * v)
        axes = np.diff(pts, axis=0) / seglen[:, None]
        fx = orthonormal_x(axes[0])[0]
        for k in range(len(axes)):
            a = axes[k]
            if k > 0:
                fx = _rotate_minimally(fx, axes[k - 1], a)
                fx -= a * np.dot(fx, a)
                fx /= np.linalg.norm(fx)
            n0 = a if k == 0 else _bisector(axes[k - 1], a)
            n1 = a if k == len(axes) - 1 else _bisector(a, axes[k + 1])
            rows.append(np.concatenate([pts[k] - origin, [r[k]], pts[k + 1] - origin, [r[k + 1]],
                                        n0, [v[k]], n1, [v[k + 1]], fx, [g]]))
    return np.array(rows, np.float64).reshape(-1, SEGMENT_FLOATS)


def _random_polylines(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Guides of mixed point counts, with the cases that take other branches: axis-aligned, exact
    fold-backs (180-degree joints), a repeated point, all points equal, nearly straight."""
    out = []
    for _ in range(n):
        m = int(rng.integers(1, 12))
        steps = rng.normal(size=(max(m - 1, 0), 3))
        kind = rng.integers(0, 6)
        if kind == 0:
            steps[:] = [0, 0, 1]
        elif kind == 1:
            steps[1::2] = -steps[0::2][: len(steps[1::2])]
        elif kind == 2 and m > 1:
            steps[rng.integers(0, m - 1)] = 0
        elif kind == 3:
            steps[:] = 0
        elif kind == 4:
            steps = [0, 0, 1] + 1e-9 * steps
        out.append(np.concatenate([rng.normal(size=(1, 3)) * 10, steps]).cumsum(axis=0))
    return out


@pytest.mark.parametrize("seed", range(20))
def test_from_polylines_equals_the_per_segment_loop(seed: int) -> None:
    rng = np.random.default_rng(seed)
    polylines = _random_polylines(rng, int(rng.integers(1, 40)))
    radii = rng.uniform(0.05, 0.5, len(polylines)) if seed % 2 else 0.2
    taper = float(rng.uniform(0, 1))
    scene = Scene.from_polylines(polylines, radii, taper=taper)
    expected = rows_one_by_one(polylines, radii, taper, scene.origin)
    assert scene.n_guides == len(polylines)
    assert scene.segments.shape == expected.shape
    # Guide index and order exactly; the arithmetic to float32 rounding (np.dot against row sums).
    np.testing.assert_array_equal(scene.segments[:, 19], expected[:, 19])
    np.testing.assert_allclose(scene.segments, expected.astype(np.float32), rtol=1e-6, atol=1e-6)


def test_equal_guides_as_one_array_or_a_list() -> None:
    rng = np.random.default_rng(3)
    guides = np.concatenate([rng.normal(size=(50, 1, 3)), rng.normal(size=(50, 6, 3))], axis=1).cumsum(axis=1)
    radii = rng.uniform(0.1, 0.3, 50)
    a = Scene.from_polylines(guides, radii, taper=0.5)
    b = Scene.from_polylines(list(guides), radii, taper=0.5)
    np.testing.assert_array_equal(a.segments, b.segments)
    np.testing.assert_array_equal(a.origin, b.origin)
    rows = container_rows(guides, radii, 0.5, a.origin).astype(np.float32)
    np.testing.assert_array_equal(rows, a.segments)


def test_degenerate_guides_make_no_container() -> None:
    point, twice = np.zeros((1, 3)), np.zeros((2, 3))
    scene = Scene.from_polylines([point, twice, np.array([[0, 0, 0], [0, 0, 1.0]])], 0.1)
    assert scene.n_segments == 1 and scene.n_guides == 3 and scene.segments[0, 19] == 2
    assert Scene.from_polylines([], 0.1).n_segments == 0
    with pytest.raises(ValueError, match="guides: at most"):
        Scene.from_polylines(np.zeros((MAX_GUIDES + 1, 0, 3)), 0.1)
