"""Case 7's frames: smooth through the axis directions and, now, everywhere but at the one singular
direction of the frame field (the hairy ball theorem allows no fewer)."""

from __future__ import annotations

import numpy as np
import pytest

from app.scene.containers import SINGULAR_AXIS, orthonormal_x

S = SINGULAR_AXIS
P = np.cross(S, [1.0, 0.0, 0.0]) / np.linalg.norm(np.cross(S, [1.0, 0.0, 0.0]))
Q = np.cross(S, P)


def around(theta, phi):
    """Unit directions at angle theta from the singular direction, azimuth phi about it."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    return (np.cos(theta)[..., None] * S + np.sin(theta)[..., None]
            * (np.cos(phi)[..., None] * P + np.sin(phi)[..., None] * Q)).reshape(-1, 3)


def test_no_jump_where_the_basis_used_to_switch():
    """Regression: within 1.4e-3 rad of SINGULAR_AXIS (1 + z < 1e-6) the basis switched to a fixed vector,
    so a guide crossing that circle flipped its fiber pattern by up to 180 degrees (|dx| = 2)."""
    edge = np.arccos(1.0 - 1e-6)
    phi = np.linspace(0, 2 * np.pi, 256, endpoint=False)
    inside, outside = orthonormal_x(around(edge - 1e-8, phi)), orthonormal_x(around(edge + 1e-8, phi))
    assert np.linalg.norm(inside - outside, axis=1).max() < 1e-6


@pytest.mark.parametrize("theta", np.logspace(-10, -1, 10))
def test_the_basis_turns_no_faster_than_the_winding_allows(theta):
    """About its singular point the field turns by twice the azimuth: a tilt d at angle theta turns it by
    about 2 d / theta, never more (and never a jump)."""
    phi = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    d = 1e-3 * theta
    for a, b in ((around(theta, phi), around(theta, phi + d / np.sin(theta))),     # across
                 (around(theta, phi), around(theta + d, phi))):                       # outward
        change = np.linalg.norm(orthonormal_x(a) - orthonormal_x(b), axis=1)
        assert change.max() <= 2.05 * d / theta + 1e-9


def test_orthonormal_everywhere_including_the_singular_direction():
    z = np.concatenate([around(np.logspace(-16, 0.49, 200)[:, None], np.linspace(0, 6.2, 7)[None]),
                        S[None], -S[None], np.eye(3), -np.eye(3)])
    x = orthonormal_x(z)
    assert np.isfinite(x).all()
    assert np.abs(np.linalg.norm(x, axis=1) - 1).max() < 1e-12
    assert np.abs((x * z).sum(1)).max() < 1e-12
