"""Colour parameters to shader inputs: the look's base colour, including Cycles' melanin model.

The melanin conversion is the one of Blender Cycles' Principled Hair BSDF (melanin amount and redness to
eumelanin and pheomelanin concentrations, to an absorption coefficient), so a look tuned here exports to
the same hair closure in OSL. The preview needs a colour: the reflectance Cycles would associate with
that absorption, inverting its ``sigma_from_reflectance`` at the default radial roughness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..params import Params

EUMELANIN_SIGMA = np.array([0.506, 0.841, 1.653])
PHEOMELANIN_SIGMA = np.array([0.343, 0.733, 1.924])
RADIAL_ROUGHNESS = 0.3          # Cycles' default for the Principled Hair BSDF


def melanin_to_sigma(melanin: float, redness: float) -> np.ndarray:
    """Absorption coefficient (per unit fiber diameter) from melanin amount and redness."""
    quantity = -math.log(max(1.0 - melanin, 1e-4))
    return quantity * ((1.0 - redness) * EUMELANIN_SIGMA + redness * PHEOMELANIN_SIGMA)


def roughness_factor(radial_roughness: float) -> float:
    x = radial_roughness
    return (((((0.245 * x) + 5.574) * x - 10.73) * x + 2.532) * x - 0.215) * x + 5.969


def sigma_to_color(sigma: np.ndarray, radial_roughness: float = RADIAL_ROUGHNESS) -> np.ndarray:
    """Inverse of Cycles' sigma_from_reflectance: sigma = (log(c) / factor)^2."""
    return np.exp(-np.sqrt(np.maximum(sigma, 0.0)) * roughness_factor(radial_roughness))


def base_color(p: Params) -> tuple[float, float, float]:
    if p["look.color_mode"] == "melanin":
        c = sigma_to_color(melanin_to_sigma(p["look.melanin"], p["look.melanin_redness"]))
        return tuple(float(v) for v in c)
    return tuple(float(v) for v in p["look.color"])


def tip_color(p: Params) -> tuple[float, float, float]:
    """The colour a strand blends to toward its tip: ``look.tip_color``, or in melanin mode the colour of
    ``look.tip_melanin`` at the root's redness (the same conversion as :func:`base_color`)."""
    if p["look.color_mode"] == "melanin":
        c = sigma_to_color(melanin_to_sigma(p["look.tip_melanin"], p["look.melanin_redness"]))
        return tuple(float(v) for v in c)
    return tuple(float(v) for v in p["look.tip_color"])


def tip_weight(v, blend: float, start: float):
    """How much of the tip colour a fiber shows at guide parameter ``v`` (0 root .. 1 tip): 0 up to
    ``start``, then a smoothstep to ``blend`` at the tip. Twin: glsl/shading/fiber_color.glsl tip_weight.
    ``start`` = 1 gives 0 everywhere (the divisor's floor keeps it finite)."""
    t = np.clip((np.asarray(v, np.float64) - start) / max(1.0 - start, 1e-4), 0.0, 1.0)
    return blend * t * t * (3.0 - 2.0 * t)


def fiber_color(v, tint, p: Params, root=None, tip_file=None) -> np.ndarray:
    """Linear albedo of fibers at guide parameter ``v`` with per-fiber tint key ``tint`` in [-0.5, 0.5]
    (broadcast together; returns (..., 3)). ``root``/``tip_file``: the groom file's colours of the fiber's
    guide at its root and tip ((..., 3), from ``Scene.guide_colors``) when ``look.color_source`` = file;
    they replace the look's colour along the strand, linearly from root to tip. The look's tip blend then
    goes toward :func:`tip_color` on top, and the random tint scales the result.
    Twin: glsl/shading/fiber_color.glsl fiber_color (the shader mixes in float32)."""
    v = np.asarray(v, np.float64)
    tint = np.asarray(tint, np.float64)
    base = np.asarray(base_color(p), np.float64)
    if root is not None:
        root = np.asarray(root, np.float64)
        tip_file = root if tip_file is None else np.asarray(tip_file, np.float64)
        base = root + (tip_file - root) * np.clip(v, 0.0, 1.0)[..., None]
    w = tip_weight(v, p["look.tip_blend"], p["look.tip_start"])[..., None]
    c = base + (np.asarray(tip_color(p), np.float64) - base) * w
    return np.clip(c * (1.0 + p["look.tint_variation"] * 2.0 * tint[..., None]), 0.0, 1.0)


def fiber_density(p: Params, fibers_per_container: int) -> float:
    """Fiber cross-section met per unit length of a light path in unit space (container radius 1):
    fibers per unit area times fiber diameter. Drives the density self-shadow estimate."""
    return fibers_per_container / math.pi * 2.0 * p["fibers.fiber_radius"]


# --------------------------------------------------------------------------------------------------
# lights: key, fill, rim and the environment, as plain data (the shader's uniforms, the Blender export)
# --------------------------------------------------------------------------------------------------
MAX_LIGHTS = 12                 # glsl/shading/light.glsl: fill + rim + the environment's median-cut lights


@dataclass(frozen=True)
class Light:
    """One directional light. ``direction`` points toward the light (world, +Z up); ``color`` is linear RGB
    times intensity. ``kind``: key, fill, rim or environment (a median-cut piece of the environment)."""

    kind: str
    direction: tuple[float, float, float]
    color: tuple[float, float, float]


@dataclass(frozen=True)
class Environment:
    """The image-based light as an exporter needs it: a lat-long image (a file, or one of the generated
    maps by name: ``environment.generated``), turned about +Z by ``rotation`` degrees, times ``intensity``."""

    source: str                 # a file path, or "studio" / "sky"
    generated: bool
    rotation: float
    intensity: float


def _direction(azimuth: float, elevation: float) -> tuple[float, float, float]:
    az, el = math.radians(azimuth), math.radians(elevation)
    return (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))


def environment(p: Params) -> Environment | None:
    from ..params import ParamError
    from .environment import GENERATED

    mode = p["light.environment"]
    if mode == "off":
        return None
    if mode == "file":
        path = p["light.environment_file"]
        if not path:
            raise ParamError("light.environment = 'file' needs light.environment_file (a lat-long .exr or "
                             ".hdr)", key="light.environment_file")
        return Environment(path, False, p["light.environment_rotation"] + p["light.rig_rotation"],
                           p["light.environment_intensity"])
    assert mode in GENERATED
    return Environment(mode, True, p["light.environment_rotation"] + p["light.rig_rotation"],
                       p["light.environment_intensity"])


def lights(p: Params, camera_azimuth: float | None = None, *, environment_pieces: bool = True) -> list[Light]:
    """Every light of the look, key first. The rim follows the camera (``camera_azimuth``, default the
    parameters' ``camera.azimuth``): it stays behind the hair however the view turns. Without
    ``environment_pieces`` the environment's median-cut lights are left out (an exporter that gives the
    renderer the image itself, ``environment(p)``, wants the lamps only)."""
    from ..params import ParamError
    from .environment import EnvironmentError_, environment_lights, rotate_z

    rig = p["light.rig_rotation"]
    key = _direction(p["look.light_azimuth"] + rig, p["look.light_elevation"])
    out = [Light("key", key, (p["look.light_intensity"],) * 3)]
    if p["light.fill_intensity"] > 0:
        c = tuple(p["light.fill_intensity"] * x for x in p["light.fill_color"])
        out.append(Light("fill", _direction(p["light.fill_azimuth"] + rig, p["light.fill_elevation"]), c))
    if p["light.rim_intensity"] > 0:
        cam_az = p["camera.azimuth"] if camera_azimuth is None else camera_azimuth
        # the camera sits at cam_az looking at the hair; straight behind the hair is cam_az + 180
        c = tuple(p["light.rim_intensity"] * x for x in p["light.rim_color"])
        out.append(Light("rim", _direction(cam_az + 180.0 + p["light.rim_azimuth"], p["light.rim_elevation"]), c))
    env = environment(p)
    if env is not None and env.intensity > 0 and environment_pieces:
        try:
            pieces = environment_lights(env.source)
        except EnvironmentError_ as e:
            raise ParamError(str(e), key="light.environment_file") from None
        for piece in pieces:
            out.append(Light("environment", rotate_z(piece.direction, env.rotation),
                             tuple(env.intensity * x for x in piece.color)))
    return out


def apply_lighting(prog, p: Params, camera_position=None, scene_centre=None) -> None:
    """Set light.glsl's uniforms on ``prog``: the key light (its shadow is traced or estimated by the
    caller's shader) and up to MAX_LIGHTS others. The camera's azimuth comes from its position when given
    (the viewer's orbit), else from ``camera.azimuth``."""
    cam_az = None
    if camera_position is not None and scene_centre is not None:
        d = np.asarray(camera_position, np.float64) - np.asarray(scene_centre, np.float64)
        cam_az = math.degrees(math.atan2(d[1], d[0]))
    all_lights = lights(p, cam_az)
    key, others = all_lights[0], all_lights[1:MAX_LIGHTS + 1]
    dirs = np.zeros((MAX_LIGHTS, 3), np.float32)
    colors = np.zeros((MAX_LIGHTS, 3), np.float32)
    for i, light in enumerate(others):
        dirs[i], colors[i] = light.direction, light.color
    if "uLightDir" in prog:
        prog["uLightDir"].value = key.direction
    if "uLightCount" in prog:
        prog["uLightCount"].value = len(others)
    if "uLightDirs" in prog:
        prog["uLightDirs"].write(dirs.tobytes())
    if "uLightColors" in prog:
        prog["uLightColors"].write(colors.tobytes())


def light_rig(p: Params, folder: str | None = None) -> dict:
    """The look's lights for an exporter (Blender's export-blend), as JSON-ready data: sun lamps with a
    direction toward the light and a linear RGB strength, and the environment as an equirectangular image
    (``folder``: where a generated map is written as .hdr, so the exporter has a file to load) with its
    rotation about +Z and strength. Same conventions as Blender's: +Z up, the image's centre column
    looking along +X."""
    from pathlib import Path

    from .environment import environment_image, write_hdr

    rig: dict = {"lights": [{"kind": x.kind, "direction": list(x.direction), "color": list(x.color)}
                            for x in lights(p, environment_pieces=False)],
                 "environment": None, "ambient": p["look.ambient"]}
    env = environment(p)
    if env is not None:
        path = env.source
        if env.generated and folder is not None:
            target = Path(folder) / f"vfiber-{env.source}.hdr"
            write_hdr(target, environment_image(env.source))
            path = str(target)
        rig["environment"] = {"image": path, "generated": env.generated, "rotation_degrees": env.rotation,
                              "strength": env.intensity}
    return rig


# --------------------------------------------------------------------------------------------------
# swatches: what a colour looks like on screen (the panel), with the shader's own terms in numpy
# --------------------------------------------------------------------------------------------------
DISPLAY_GAMMA = 2.2             # glsl/shading/light.glsl tone_map and renderer._composite


def display_color(linear) -> tuple[int, int, int]:
    """A linear colour as the renderer's display space writes it (the power 1 / 2.2 of tone_map and of the
    background), in 8-bit levels: the swatch of a colour *value*, as Blender shows a scene-linear colour
    through its display transform. imgui's colour editor would show the linear numbers as if they were
    display values, which makes (0.55, 0.36, 0.2) look like sRGB (140, 92, 51) rather than (194, 160, 123)."""
    c = np.clip(np.asarray(linear, np.float64), 0.0, 1.0) ** (1.0 / DISPLAY_GAMMA)
    return tuple(int(v) for v in np.round(c * 255.0))


def tone_map(radiance, exposure: float = 0.0) -> np.ndarray:
    """Twin of light.glsl tone_map: exposure, Reinhard, then the display power; values in [0, 1]."""
    c = np.asarray(radiance, np.float64) * 2.0 ** exposure
    return np.clip(c / (1.0 + c), 0.0, 1.0) ** (1.0 / DISPLAY_GAMMA)


def _dot(a, b):
    return (a * b).sum(-1)


def _kk_lobe(T, V, L, shift, exponent):
    Ts = T + shift * np.cross(T, np.cross(V, T))
    Ts = Ts / np.linalg.norm(Ts, axis=-1, keepdims=True)
    tl, tv = _dot(Ts, L), _dot(Ts, V)
    c = np.sqrt(np.maximum(0.0, 1 - tl * tl)) * np.sqrt(np.maximum(0.0, 1 - tv * tv)) - tl * tv
    return np.maximum(c, 0.0) ** exponent


def kajiya_kay(T, N, V, L, albedo, roughness):
    """Twin of kajiya_kay.glsl shade_kajiya_kay (rows of vectors; albedo (..., 3))."""
    tl = _dot(T, L)
    diffuse = 0.5 * (np.sqrt(np.maximum(0.0, 1 - tl * tl)) + np.maximum(_dot(N, L), 0.0))
    exponent = 2.0 / max(roughness * roughness, 1e-4)
    primary = _kk_lobe(T, V, L, -0.1, exponent)
    secondary = _kk_lobe(T, V, L, 0.15, 0.5 * exponent)
    return (albedo * (diffuse * 0.8)[..., None] + 0.12 * primary[..., None]
            + 0.25 * albedo * secondary[..., None])


def _gauss(beta, x):
    return np.exp(-0.5 * x * x / (beta * beta)) / (2.50662827 * beta)


def _fresnel(c):
    m = 1.0 - np.clip(c, 0.0, 1.0)
    return 0.04652 + (1 - 0.04652) * m ** 5


def marschner(T, V, L, color, roughness):
    """Twin of marschner.glsl shade_marschner."""
    tilt = 0.035
    sinL, sinV = np.clip(_dot(T, L), -1, 1), np.clip(_dot(T, V), -1, 1)
    cosD = np.cos(0.5 * np.abs(np.arcsin(sinV) - np.arcsin(sinL)))
    Lp, Vp = L - sinL[..., None] * T, V - sinV[..., None] * T
    cosPhi = _dot(Lp, Vp) / np.sqrt(_dot(Lp, Lp) * _dot(Vp, Vp) + 1e-4)
    cosHalf = np.sqrt(np.clip(0.5 + 0.5 * cosPhi, 0, 1))
    beta = max(roughness * roughness, 0.01)
    sa, ca = math.sin(-2 * tilt), math.cos(-2 * tilt)
    shift = 2 * sa * (ca * cosHalf * np.sqrt(1 - sinV * sinV) + sa * sinV)
    mr = _gauss(beta * 1.41421356 * np.maximum(cosHalf, 0.05), sinL + sinV - shift)
    S = (mr * 0.25 * cosHalf * _fresnel(np.sqrt(np.clip(0.5 + 0.5 * _dot(V, L), 0, 1))))[..., None] * np.ones(3)
    n_prime = 1.19 / cosD + 0.36 * cosD
    a = 1 / n_prime
    h = cosHalf * (1 + a * (0.6 - 0.8 * cosPhi))
    f = _fresnel(cosD * np.sqrt(np.clip(1 - h * h, 0, 1)))
    ttt = color ** (0.5 * np.sqrt(np.maximum(0, 1 - h * h * a * a)) / cosD)[..., None]
    S = S + (_gauss(0.5 * beta, sinL + sinV - tilt) * np.exp(-3.65 * cosPhi - 3.98) * (1 - f) ** 2)[..., None] * ttt
    f = _fresnel(0.5 * cosD)
    S = S + (_gauss(2 * beta, sinL + sinV - 4 * tilt) * np.exp(17 * cosPhi - 16.78) * (1 - f) ** 2 * f)[..., None] \
        * color ** (0.8 / cosD)[..., None]
    return S + color * (0.25 * np.sqrt(np.maximum(0, 1 - sinL * sinL)))[..., None]


SWATCH_SAMPLES = 24             # per axis: rays across the clump, and depths/normals along each


def lit_samples(p: Params, albedo, view_dir=None) -> np.ndarray:
    """Display colours (0..1, (n, 3)) of fibers of one ``albedo`` in a vertical clump (+Z, a straight
    container) seen from ``view_dir`` (toward the camera; default the camera's orbit direction), under
    the look's key light, its other lights and the sky fill, with the shader's self-shadow and occlusion.

    Where the shader traverses real fibers, this takes the rings as a medium: a ray across the clump meets
    its first fiber with the probability each ring's fiber cross-section per unit length gives (its fiber
    count times a diameter over its annulus' area), and sees the half of that fiber facing it; the light
    reaching that fiber is the shader's own density estimate. SWATCH_SAMPLES rays across the clump, as many
    depth quantiles per ray and positions across the fiber."""
    from .. import fibers

    lay = fibers.ring_layout(p)
    density = fiber_density(p, lay.fibers_per_container)
    if view_dir is None:
        view_dir = _direction(p["camera.azimuth"], p["camera.elevation"])
    V = np.asarray(view_dir, np.float64)
    V = V / np.linalg.norm(V)
    vxy = V[:2] / max(np.linalg.norm(V[:2]), 1e-9)          # the view across the clump, toward the camera
    side = np.array([-vxy[1], vxy[0]])
    n = SWATCH_SAMPLES
    q = (np.arange(n) + 0.5) / n
    # optical depth along each ray (from the front surface inward), by ring
    K = lay.rings
    edges = 1.0 - np.arange(K + 1) / K                        # ring k spans [edges[k + 1], edges[k]]
    ring_density = lay.n * 2.0 * lay.fiber_radius / (math.pi * (edges[:-1] ** 2 - edges[1:] ** 2))
    steps = 256
    x = 2 * q - 1
    entry = np.sqrt(np.maximum(0.0, 1 - x * x))
    s = np.linspace(0.0, 1.0, steps + 1)[None, :] * (2 * entry)[:, None]       # (rays, steps + 1)
    r = np.sqrt(x[:, None] ** 2 + (entry[:, None] - s) ** 2)
    k = np.clip(((1.0 - r) * K).astype(np.int64), 0, K - 1)
    tau = np.concatenate([np.zeros((n, 1)), np.cumsum(0.5 * (ring_density[k[:, 1:]] + ring_density[k[:, :-1]])
                                                      * np.diff(s, axis=1), axis=1)], axis=1)
    hit = 1.0 - np.exp(-tau)
    # the depth of the first fiber at each quantile of the hit probability, per ray: (rays, quantiles)
    depth = np.stack([np.interp(q * hit[i, -1], hit[i], s[i]) for i in range(n)])
    # every (ray, depth quantile) pair with every position across the fiber
    x = np.repeat(x, n * n)
    depth = np.repeat(depth.ravel(), n)
    u = np.tile(2 * q - 1, n * n)
    entry = np.sqrt(np.maximum(0.0, 1 - x * x))
    c = x[:, None] * side + (entry - depth)[:, None] * vxy     # where that fiber sits in the unit disc
    T = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (len(x), 3))
    # the fiber's normal across its visible half: sideways to the fiber and the view, toward the viewer
    S = np.cross(T, V)
    S = S / max(np.linalg.norm(S[0]), 1e-9)
    F = np.cross(S, T)
    N = S * u[:, None] + F * np.sqrt(np.maximum(0.0, 1 - u * u))[:, None]
    shadow = p["look.shadow_density"] if p["look.self_shadow"] != "off" else 0.0
    occlusion = 1.0 + (np.exp(-3.0 * (1 - np.linalg.norm(c, axis=1))) - 1.0) * p["look.shadow_density"]

    def through(L, scale):
        # light.glsl density_transmittance / fiber_shading.glsl light_transmittance on a straight clump:
        # the path from c to the wall along L's horizontal part, in the light's unit direction
        Lxy = np.asarray(L[:2])
        dd = max(float(Lxy @ Lxy), 1e-6)
        b = c @ Lxy
        t = (-b + np.sqrt(np.maximum(b * b - dd * ((c * c).sum(1) - 1), 0.0))) / dd
        return np.exp(-scale * shadow * density * np.minimum(t, 4.0 if scale < 1 else np.inf))

    albedo = np.broadcast_to(np.asarray(albedo, np.float64), (len(x), 3))
    rough = p["look.roughness"]

    def model(L):
        Lr = np.broadcast_to(np.asarray(L, np.float64), (len(x), 3))
        Vr = np.broadcast_to(V, (len(x), 3))
        if p["look.model"] == "marschner":
            return marschner(T, Vr, Lr, albedo, rough)
        return kajiya_kay(T, N, Vr, Lr, albedo, rough)

    all_lights = lights(p)
    key = np.asarray(all_lights[0].direction)
    radiance = p["look.light_intensity"] * through(key, 1.0)[:, None] * model(key)
    radiance += p["look.ambient"] * occlusion[:, None] * albedo * (0.55 + 0.45 * np.maximum(N[:, 2], 0))[:, None]
    for light in all_lights[1:MAX_LIGHTS + 1]:
        radiance += np.asarray(light.color) * through(light.direction, 0.25)[:, None] * model(light.direction)
    return tone_map(radiance, p["look.exposure"])


def lit_swatch(p: Params, albedo=None, view_dir=None) -> tuple[int, int, int]:
    """The 'as lit' swatch: the median display colour (8-bit) of :func:`lit_samples` for ``albedo``
    (default the look's base colour). What a lit clump of this colour shows on screen, tone map,
    sky fill, white highlight, self-shadow and occlusion included."""
    albedo = base_color(p) if albedo is None else albedo
    c = np.median(lit_samples(p, albedo, view_dir), axis=0)
    return tuple(int(v) for v in np.round(c * 255.0))
