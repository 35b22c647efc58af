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
        base = root + (tip_file - root) * v[..., None]
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
