"""Every user-facing parameter of vfiber, declared once.

This table is the single source of truth: presets validate against it, the viewer builds its sliders from
it, the command line's ``--set key=value`` parses with it, the OSL export writes its ``min``/``max``/``help``
metadata from it and ``docs/parameters.md`` is generated from it (a test keeps the two equal).

Keys are ``group.name``; a preset file stores them as TOML tables (``[fibers] rings = 10``).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from .errors import VfiberError


class ParamError(VfiberError, ValueError):
    """A parameter value a person supplied is unusable. The message names the key, the value and what is
    allowed; ``source`` (a file name, ``--set`` or ``slider``) is prefixed when known."""

    def __init__(self, message: str, *, key: str | None = None, source: str | None = None,
                 line: int | None = None):
        self.key, self.source, self.line, self.bare = key, source, line, message
        where = ""
        if source:
            where = f"{source}:{line}: " if line else f"{source}: "
        super().__init__(where + message)


@dataclass(frozen=True)
class Param:
    key: str
    kind: type                       # int, float, str, bool or tuple (3 floats: a colour or a point)
    default: Any
    help: str
    lo: float | None = None          # inclusive bounds for int/float (each component for tuples)
    hi: float | None = None
    unit: str = ""
    choices: tuple[str, ...] = ()    # allowed values of a str parameter; empty = free text (a path)

    @property
    def group(self) -> str:
        return self.key.split(".", 1)[0]

    @property
    def name(self) -> str:
        return self.key.split(".", 1)[1]

    def allowed(self) -> str:
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind is bool:
            return "true or false"
        if self.kind is tuple:
            return f"3 numbers, each in [{_fmt(self.lo)}, {_fmt(self.hi)}]"
        if self.kind is str:
            return "a string"
        kind = "an integer" if self.kind is int else "a number"
        return f"{kind} in [{_fmt(self.lo)}, {_fmt(self.hi)}]" + (f" {self.unit}" if self.unit else "")

    def check(self, value: Any) -> Any:
        """Return the value coerced to this parameter's type, or raise ParamError."""
        bad = lambda why="": ParamError(  # noqa: E731
            f"{self.key} = {short_repr(value)} is not allowed{why}: expected {self.allowed()}", key=self.key)
        if self.kind is bool:
            if isinstance(value, bool):
                return value
            raise bad()
        if self.kind is str:
            if not isinstance(value, str):
                raise bad()
            if self.choices and value not in self.choices:
                near = difflib.get_close_matches(value, self.choices, n=1)
                raise bad(f" (did you mean {near[0]!r}?)" if near else "")
            return value
        if self.kind is tuple:
            if not isinstance(value, (list, tuple)) or len(value) != 3:
                raise bad()
            return tuple(self._number(v, float, bad) for v in value)
        return self._number(value, self.kind, bad)

    def _number(self, value, kind, bad):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise bad()
        if kind is int:
            if isinstance(value, float):
                if not value.is_integer():
                    raise bad()
                value = int(value)
        else:
            try:
                value = float(value)
            except OverflowError:  # an integer too large for a float
                raise bad(" (out of range)") from None
            if not math.isfinite(value):
                raise bad(" (not finite)")
        if (self.lo is not None and value < self.lo) or (self.hi is not None and value > self.hi):
            raise bad(" (out of range)")
        return value


def short_repr(value: Any, limit: int = 60) -> str:
    """repr() cut to a readable length: a 400-digit number in a message helps nobody."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _fmt(x: float | None) -> str:
    if x is None:
        return "-inf"
    if float(x).is_integer() and abs(x) < 1e15:
        return str(int(x))  # 2147483647, not 2.14748e+09
    return f"{x:g}"


P = Param
SPEC: tuple[Param, ...] = (
    # --- scene: which containers exist (the scene never stores fibers) ---
    P("scene.generator", str, "carpet", "what builds the containers", choices=(
        "single", "carpet", "furball", "curved", "groom")),
    P("scene.count", int, 24, "number of guide hairs (containers chains) a generator makes", 1, 200_000),
    P("scene.radius", float, 0.1, "container (hair cylinder) radius at the root", 1e-6, 1e6, "units"),
    P("scene.length", float, 1.0, "guide hair length", 1e-6, 1e7, "units"),
    P("scene.taper", float, 0.0, "tip radius is (1 - taper) times the root radius", 0.0, 0.95),
    P("scene.segments", int, 1, "container segments per guide (>1 bends the guide)", 1, 64),
    P("scene.bend", float, 0.0, "total bend of a generated guide from root to tip", 0.0, 179.0, "degrees"),
    P("scene.seed", int, 1, "seed of the generator's placement", 0, 2**31 - 1),
    P("scene.groom_file", str, "", "groom file (.hair .data .tfx .ply) when generator = 'groom'"),
    P("scene.groom_up", str, "auto", "up axis of the groom file", choices=("auto", "y", "z", "-x", "x")),
    P("scene.groom_scale", float, 1.0, "scale applied to the groom file's coordinates", 1e-6, 1e6),
    P("scene.groom_radius_scale", float, 1.0, "clump size of a groom: its container radius (from the spacing "
      "of the roots, or what a cluster's strands need) times this", 0.05, 20.0),
    P("scene.groom_children", int, 0, "interpolated child guides per guide: thinner containers between the "
      "strands, each blended from its nearest strands (Blender's Interpolated children), for curls tighter "
      "than a container is wide; 0 = none", 0, 31),
    P("scene.groom_cluster", int, 0, "cluster strands into this many thick containers (0 = one per strand)",
      0, 100_000),

    # --- fibers: the virtual-fiber layout inside each container (thesis 3.3-3.8, 4.3) ---
    P("fibers.rings", int, 10, "internal cylinders (rings) per container", 1, 64),
    P("fibers.phi_step", float, 1.0, "angle between neighbouring fibers on the outer ring", 0.01, 180.0,
      "degrees"),
    P("fibers.phi_increment", float, 0.0, "phi_step grows by this much per ring inward (thesis 4.3)",
      0.0, 30.0, "degrees"),
    P("fibers.even_spacing", float, 0.0, "0: same angle on every ring; 1: same arc length (thesis 3.6)",
      0.0, 1.0),
    P("fibers.edge_density", float, 1.0, "clump profile: fiber density on the outermost ring as a fraction "
      "of the core's; below 1 the outer rings thin out, so the clump has no hard wall and neighbours blend",
      0.02, 1.0),
    P("fibers.edge_width", float, 0.5, "clump profile: how far in from the edge the density thins, as a "
      "fraction of the container radius (fibers.edge_density)", 0.05, 1.0),
    P("fibers.edge_thickness", float, 1.0, "clump profile: fiber thickness on the outermost ring as a "
      "fraction of fibers.fiber_radius; it thins over fibers.edge_width as the density does", 0.05, 1.0),
    P("fibers.fiber_radius", float, 0.01, "fiber radius as a fraction of the container radius; at most "
      "0.5 / rings so a fiber fits its ring", 0.0, 0.5),
    P("fibers.radial_jitter", float, 0.5, "radial offset as a fraction of the most that keeps the fiber in "
      "its slot (thesis 3.5)", 0.0, 1.0),
    P("fibers.angular_jitter", float, 0.5, "angular offset as a fraction of the most that keeps the fiber "
      "in its slot (thesis 3.5)", 0.0, 1.0),
    P("fibers.length_jitter", float, 0.2, "fibers end up to this fraction short of the tip (thesis 3.7)",
      0.0, 1.0),
    P("fibers.groom_auto", bool, True, "grooms: choose interpolated children (where containers would fold in "
      "tight curls), rings, spacing, fiber thickness and a soft clump edge from the groom (its strand spacing "
      "and curl, the default camera's pixel size); values you set yourself win"),
    P("fibers.hash", str, "integer", "per-fiber random numbers: integer hash of (guide, ring, fiber) or the "
      "thesis's fract(1207.523 * phi)", choices=("integer", "thesis")),
    P("fibers.seed", int, 0, "seed of the per-fiber random numbers", 0, 2**31 - 1),

    # --- strand: how each virtual fiber is drawn along its own length (issue 15) ---
    P("strand.tip_width", float, 1.0, "width of a fiber at its own tip, as a fraction of its root width "
      "(fibers.fiber_radius): 1 keeps blunt cylinders, 0 ends each fiber in a point", 0.0, 1.0),
    P("strand.taper_start", float, 0.5, "where along each fiber's own length the thinning toward the tip "
      "begins: 0 at the root, 0.9 only the last tenth", 0.0, 0.95),

    # --- shape: fibers that are not straight pins (thesis 3.10) ---
    P("shape.ellipsoid", float, 0.0, "0: rings follow the cylinder; 1: rings follow the inscribed "
      "ellipsoid (thesis Figure 27)", 0.0, 1.0),
    P("shape.curl_amplitude", float, 0.0, "curl radius as a fraction of the ring width", 0.0, 0.5),
    P("shape.curl_frequency", float, 4.0, "curl turns per container length", 0.0, 64.0, "turns"),
    P("shape.curl_pattern", str, "helix", "helix: fibers wind round their rest line; wave: they sway in "
      "one plane", choices=("helix", "wave")),
    P("shape.frizz", float, 0.0, "frizz: each fiber sways its own way, by its own amount (up to half a ring "
      "width) and at its own pace (the curl's, up to half again faster or slower)", 0.0, 1.0),
    P("shape.noise", float, 0.0, "fine wiggle on every fiber, up to a tenth of a ring width, across the "
      "frizz's sway", 0.0, 1.0),
    P("shape.noise_frequency", float, 16.0, "fine wiggles per container length", 0.0, 64.0, "turns"),
    P("shape.twist", float, 0.0, "turns of the fiber pattern about the container axis per length",
      -8.0, 8.0, "turns"),
    P("shape.twist_pattern", str, "uniform", "uniform, ramped (grows toward the tip) or alternating "
      "(direction flips ring by ring)", choices=("uniform", "ramped", "alternating")),

    # --- look ---
    P("look.model", str, "kajiya_kay", "shading model", choices=("kajiya_kay", "marschner")),
    P("look.color_mode", str, "rgb", "fiber colour from an RGB colour or from melanin concentrations",
      choices=("rgb", "melanin")),
    P("look.color", tuple, (0.55, 0.36, 0.2), "base fiber colour (linear RGB)", 0.0, 1.0),
    P("look.melanin", float, 0.5, "melanin concentration (0 white, 1 black), as in Cycles' Principled "
      "Hair", 0.0, 1.0),
    P("look.melanin_redness", float, 0.3, "fraction of pheomelanin", 0.0, 1.0),
    P("look.color_source", str, "look", "look: every strand takes the look's colour; file: strands take the "
      "groom file's own colours where it stores them (root to tip per strand)", choices=("look", "file")),
    P("look.tip_blend", float, 0.0, "how far the tips take the tip colour (0 = one colour root to tip, 1 = "
      "tips fully the tip colour)", 0.0, 1.0),
    P("look.tip_start", float, 0.5, "where along the strand the blend toward the tip colour begins (0 root, "
      "1 tip); it is complete at the tip", 0.0, 1.0),
    P("look.tip_color", tuple, (0.85, 0.72, 0.52), "tip colour (linear RGB), e.g. sun-bleached ends", 0.0, 1.0),
    P("look.tip_melanin", float, 0.2, "melanin at the tips when colour comes from melanin (redness as at the "
      "root)", 0.0, 1.0),
    P("look.roughness", float, 0.35, "longitudinal roughness", 0.02, 1.0),
    P("look.tint_variation", float, 0.15, "random per-fiber colour variation", 0.0, 1.0),
    P("look.roughness_variation", float, 0.1, "random per-fiber roughness variation", 0.0, 1.0),
    P("look.self_shadow", str, "density", "how light is attenuated inside a container",
      choices=("off", "density", "traced")),
    P("look.shadow_density", float, 0.6, "how dark the inside of a container gets", 0.0, 1.0),
    P("look.light_azimuth", float, 35.0, "key light direction about the up axis", -180.0, 180.0, "degrees"),
    P("look.light_elevation", float, 40.0, "key light height", -89.0, 89.0, "degrees"),
    P("look.light_intensity", float, 1.8, "key light intensity", 0.0, 100.0),
    P("look.ambient", float, 0.25, "environment fill intensity", 0.0, 10.0),
    P("look.background", tuple, (0.06, 0.065, 0.075), "background colour (linear RGB)", 0.0, 1.0),
    P("look.exposure", float, 0.0, "exposure before the tone map", -10.0, 10.0, "stops"),

    # --- light: fill, rim and environment light besides the key light (look.light_*) ---
    P("light.rig_rotation", float, 0.0, "turns every light (key, fill, environment) about the up axis; the "
      "rim stays behind the hair as the camera sees it", -360.0, 360.0, "degrees"),
    P("light.fill_intensity", float, 0.0, "fill light intensity (0 = off): a soft light opposite the key",
      0.0, 100.0),
    P("light.fill_azimuth", float, -120.0, "fill light direction about the up axis", -180.0, 180.0, "degrees"),
    P("light.fill_elevation", float, 15.0, "fill light height", -89.0, 89.0, "degrees"),
    P("light.fill_color", tuple, (0.75, 0.85, 1.0), "fill light colour (linear RGB)", 0.0, 1.0),
    P("light.rim_intensity", float, 0.0, "rim (back) light intensity (0 = off): lights the hair's edges "
      "from behind", 0.0, 100.0),
    P("light.rim_azimuth", float, 0.0, "rim light direction from straight behind the hair, as the camera "
      "sees it (it follows the camera)", -180.0, 180.0, "degrees"),
    P("light.rim_elevation", float, 30.0, "rim light height", -89.0, 89.0, "degrees"),
    P("light.rim_color", tuple, (1.0, 0.95, 0.9), "rim light colour (linear RGB)", 0.0, 1.0),
    P("light.environment", str, "off", "image-based light: off, a generated map (studio, sky) or a lat-long "
      ".exr/.hdr file (light.environment_file)", choices=("off", "studio", "sky", "file")),
    P("light.environment_file", str, "", "lat-long (equirectangular) .exr or .hdr image when "
      "light.environment = 'file'"),
    P("light.environment_intensity", float, 1.0, "environment light strength", 0.0, 100.0),
    P("light.environment_rotation", float, 0.0, "turns the environment image about the up axis", -360.0,
      360.0, "degrees"),

    # --- quality: the speed-for-accuracy switches ---
    P("quality.mode", str, "exact", "fast: thesis order, first hit wins; exact: nearest hit; brute: every "
      "fiber (reference)", choices=("fast", "exact", "brute")),
    P("quality.supersample", int, 1, "n x n stratified rays per pixel", 1, 4),
    P("quality.msaa", int, 0, "MSAA samples for coverage (0 = off)", 0, 8),
    P("quality.filter", str, "coverage", "antialias thin fibers by their coverage: each pixel's ray is a cone and "
      "every fiber it meets adds the share of its footprint that fiber covers, a container far below the "
      "footprint as a medium (exact mode; ids and depth stay the nearest fiber's); off: one ray, the nearest "
      "fiber's colour",
      choices=("off", "coverage")),
    P("quality.filter_width", float, 1.0, "half-width of the filtered mode's tent footprint: wider holds "
      "still better under camera moves, narrower is sharper", 0.25, 4.0, "pixels"),
    P("quality.render_scale", float, 1.0, "fraction of the output resolution actually ray cast", 0.1, 1.0),
    P("quality.visibility", str, "auto", "how a pixel finds its containers: proxies (each container drawn, "
      "a traversal per layer: fastest where few overlap), walk (a hierarchy walked nearest first: fastest "
      "for dense grooms) or auto (by the layers the proxies would stack)", choices=("auto", "proxies", "walk")),

    # --- camera: an orbit about a target; positions are float64 on the CPU ---
    P("camera.azimuth", float, 30.0, "orbit angle about the up axis", -360.0, 360.0, "degrees"),
    P("camera.elevation", float, 20.0, "orbit height angle", -89.9, 89.9, "degrees"),
    P("camera.distance", float, 0.0, "distance to the target (0 = frame the whole scene)", 0.0, 1e9,
      "units"),
    P("camera.target", tuple, (0.0, 0.0, 0.0), "point the camera looks at, relative to the scene centre",
      -1e9, 1e9),
    P("camera.fov", float, 35.0, "vertical field of view", 0.1, 170.0, "degrees"),
    P("camera.near", float, 0.0, "near plane (0 = automatic)", 0.0, 1e9, "units"),
    P("camera.far", float, 0.0, "far plane (0 = automatic)", 0.0, 1e12, "units"),
)
del P

BY_KEY: dict[str, Param] = {p.key: p for p in SPEC}
GROUPS: tuple[str, ...] = tuple(dict.fromkeys(p.group for p in SPEC))


def suggest(key: str) -> str:
    near = difflib.get_close_matches(key, BY_KEY, n=1, cutoff=0.5)
    return f" (did you mean {near[0]!r}?)" if near else ""


@dataclass(frozen=True)
class Params:
    """An immutable, validated set of parameter values. Missing keys take the defaults."""

    values: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        full = {p.key: p.default for p in SPEC}
        for key, value in self.values.items():
            if key not in BY_KEY:
                raise ParamError(f"unknown parameter {key!r}{suggest(key)}", key=key)
            full[key] = BY_KEY[key].check(value)
        object.__setattr__(self, "values", full)
        check_relations(self)

    def __getitem__(self, key: str) -> Any:
        return self.values[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.values)

    def replace(self, **changes: Any) -> Params:
        """``p.replace(**{"fibers.rings": 20})`` or ``p.replace(fibers__rings=20)``."""
        new = dict(self.values)
        for key, value in changes.items():
            new[key.replace("__", ".")] = value
        return Params(new)

    def group(self, name: str) -> dict[str, Any]:
        return {k.split(".", 1)[1]: v for k, v in self.values.items() if k.startswith(name + ".")}

    def nested(self) -> dict[str, dict[str, Any]]:
        """As TOML tables: {"fibers": {"rings": 10, ...}, ...}; tuples become lists."""
        out: dict[str, dict[str, Any]] = {}
        for key, value in self.values.items():
            group, name = key.split(".", 1)
            out.setdefault(group, {})[name] = list(value) if isinstance(value, tuple) else value
        return out

    def differs_from_default(self) -> dict[str, Any]:
        return {k: v for k, v in self.values.items() if v != BY_KEY[k].default}


def max_fiber_radius(rings: int) -> float:
    """A fiber must fit inside its ring's annulus (width 1/rings of the container radius)."""
    return 0.5 / rings


def check_relations(p: Params) -> None:
    """Constraints between parameters; each message says how to fix it."""
    rings, fr = p["fibers.rings"], p["fibers.fiber_radius"]
    if fr > max_fiber_radius(rings) * (1 + 1e-12):
        raise ParamError(
            f"fibers.fiber_radius = {fr:g} is too thick for fibers.rings = {rings}: each ring is "
            f"{1 / rings:g} of the container radius wide, so fiber_radius must be at most "
            f"{max_fiber_radius(rings):g} (0.5 / rings)", key="fibers.fiber_radius")
    if p["scene.generator"] == "groom" and not p["scene.groom_file"]:
        raise ParamError("scene.generator = 'groom' needs scene.groom_file", key="scene.groom_file")
    if "\0" in p["scene.groom_file"]:
        raise ParamError("scene.groom_file contains a NUL byte, which no file name can", key="scene.groom_file")
    near, far = p["camera.near"], p["camera.far"]
    if near and far and near >= far:
        raise ParamError(f"camera.near = {near:g} must be less than camera.far = {far:g} (or set either to 0 "
                         "for automatic)", key="camera.near")


def parse_assignment(text: str) -> tuple[str, Any]:
    """Parse one ``--set key=value`` (value in TOML syntax, bare words taken as strings). A colour or point
    may also be written without brackets: look.color=0.8,0.5,0.3."""
    import tomllib

    if "=" not in text:
        raise ParamError(f"--set {text!r}: expected key=value, e.g. fibers.rings=20", source="--set")
    key, raw = (s.strip() for s in text.split("=", 1))
    if key not in BY_KEY:
        hint = suggest(key) if len(key) <= 100 else ""  # a 2,000-part key needs no "did you mean"
        raise ParamError(f"unknown parameter {short_repr(key)}{hint}", key=key[:100], source="--set")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw  # a bare word such as fast or carpet
    except (ValueError, RecursionError):  # int()'s 4300-digit limit escapes tomllib; so does deep nesting
        raise ParamError(f"{key} = {short_repr(raw)} is not allowed: a number thousands of digits long or a "
                         f"value nested too deeply; expected {BY_KEY[key].allowed()}", key=key,
                         source="--set") from None
    if isinstance(value, str) and "," in value and BY_KEY[key].kind is tuple:
        try:
            value = [float(v) for v in value.split(",")]
        except ValueError:
            pass
    return key, value


def with_assignments(values: dict[str, Any], assignments: Iterable[str]) -> Params:
    """``values`` (a preset's, or a groom's) with every ``--set key=value`` applied, validated. An error the
    assignments caused names ``--set`` as its source (and how to write a colour, if that was the key)."""
    assignments = list(assignments)
    values = dict(values)
    for text in assignments:
        key, value = parse_assignment(text)
        values[key] = value
    try:
        return Params(values)
    except ParamError as e:
        if assignments and e.source is None:
            raise ParamError(e.bare + _tuple_hint(e.key), key=e.key, source="--set") from None
        raise


def _tuple_hint(key: str | None) -> str:
    if key in BY_KEY and BY_KEY[key].kind is tuple:
        return f" (write it as {key}=0.8,0.5,0.3 or {key}=[0.8,0.5,0.3])"
    return ""
