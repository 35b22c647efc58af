"""The panel in artists' words: sections as hair tools group them, labels a groomer recognises, the
thesis's names kept for the tooltips, and which controls apply to the scene on screen.

No imgui here (the tests read it directly). Parameter keys stay as they are (presets, ``--set``, the
OSL export use them); only what the panel shows changes.
"""

from __future__ import annotations

from collections.abc import Callable

from ..params import SPEC, Params
from ..render.renderer import filter_applies, filtered

# (title, keys) in panel order. Every SPEC key sits in exactly one section (a test checks); a key added
# to SPEC later and not placed here lands in the section of its group's first key, or "Other".
SECTIONS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Groom", ("scene.generator", "scene.groom_file", "scene.groom_up", "scene.groom_scale",
               "scene.groom_cluster", "scene.groom_radius_scale", "scene.groom_children", "scene.count",
               "scene.radius", "scene.length", "scene.taper", "scene.segments", "scene.bend", "scene.seed")),
    ("Strands and fibers", ("fibers.rings", "fibers.phi_step", "fibers.phi_increment", "fibers.even_spacing",
                            "fibers.groom_auto", "fibers.fiber_radius", "fibers.edge_density", "fibers.edge_width",
                            "fibers.edge_thickness", "fibers.radial_jitter", "fibers.angular_jitter",
                            "fibers.length_jitter", "strand.tip_width", "strand.taper_start", "fibers.hash",
                            "fibers.seed")),
    ("Shape", ("shape.curl_amplitude", "shape.curl_frequency", "shape.curl_pattern", "shape.frizz",
               "shape.noise", "shape.noise_frequency", "shape.twist", "shape.twist_pattern", "shape.ellipsoid")),
    ("Shading", ("look.model", "look.color_mode", "look.color", "look.melanin", "look.melanin_redness",
                 "look.color_source", "look.tip_blend", "look.tip_start", "look.tip_color", "look.tip_melanin",
                 "look.roughness", "look.tint_variation", "look.roughness_variation", "look.self_shadow",
                 "look.shadow_density")),
    ("Lighting", ("look.light_intensity", "look.light_azimuth", "look.light_elevation", "light.fill_intensity",
                  "light.fill_azimuth", "light.fill_elevation", "light.fill_color", "light.rim_intensity",
                  "light.rim_azimuth", "light.rim_elevation", "light.rim_color", "light.environment",
                  "light.environment_file", "light.environment_intensity", "light.environment_rotation",
                  "look.ambient", "light.rig_rotation")),
    ("Render", ("look.exposure", "look.background", "quality.mode", "quality.filter", "quality.filter_width",
                "quality.supersample", "quality.msaa", "quality.render_scale", "camera.azimuth", "camera.elevation",
                "camera.distance", "camera.target", "camera.fov", "camera.near", "camera.far")),
)
OPEN_SECTIONS = ("Groom", "Strands and fibers", "Shading", "Lighting")

LABELS: dict[str, str] = {
    "scene.generator": "hair from", "scene.groom_file": "groom file", "scene.groom_up": "up axis",
    "scene.groom_scale": "groom scale", "scene.groom_cluster": "clumps",
    "scene.groom_radius_scale": "clump size", "scene.groom_children": "interpolated children",
    "scene.count": "guide hairs",
    "scene.radius": "clump radius", "scene.length": "hair length", "scene.taper": "clump taper",
    "scene.segments": "segments per guide", "scene.bend": "bend", "scene.seed": "placement seed",
    "fibers.rings": "strand layers", "fibers.phi_step": "strand spacing", "fibers.phi_increment":
    "spacing grows inward", "fibers.even_spacing": "even gaps", "fibers.fiber_radius": "strand thickness",
    "fibers.edge_density": "edge density", "fibers.edge_width": "soft edge width",
    "fibers.edge_thickness": "edge strand thickness", "fibers.groom_auto": "groom auto",
    "fibers.radial_jitter": "scatter in/out", "fibers.angular_jitter": "scatter around",
    "fibers.length_jitter": "length variation", "strand.tip_width": "tip thickness",
    "strand.taper_start": "taper begins", "fibers.hash": "random pattern", "fibers.seed": "strand seed",
    "shape.curl_amplitude": "curl size", "shape.curl_frequency": "curls per length",
    "shape.curl_pattern": "curl type", "shape.frizz": "frizz", "shape.noise": "fine wiggle",
    "shape.noise_frequency": "wiggles per length", "shape.twist": "twist", "shape.twist_pattern": "twist type",
    "shape.ellipsoid": "rounded clump ends",
    "look.model": "hair shader", "look.color_mode": "colour from", "look.color": "colour",
    "look.melanin": "melanin", "look.melanin_redness": "redness", "look.roughness": "roughness",
    "look.color_source": "groom colours", "look.tip_blend": "tip blend", "look.tip_start": "tip blend starts",
    "look.tip_color": "tip colour", "look.tip_melanin": "tip melanin",
    "look.tint_variation": "colour variation", "look.roughness_variation": "roughness variation",
    "look.self_shadow": "self-shadowing", "look.shadow_density": "shadow depth",
    "look.light_intensity": "key intensity", "look.light_azimuth": "key direction",
    "look.light_elevation": "key height", "look.ambient": "sky fill",
    "light.fill_intensity": "fill intensity", "light.fill_azimuth": "fill direction",
    "light.fill_elevation": "fill height", "light.fill_color": "fill colour",
    "light.rim_intensity": "rim intensity", "light.rim_azimuth": "rim direction",
    "light.rim_elevation": "rim height", "light.rim_color": "rim colour",
    "light.environment": "environment (HDRI)", "light.environment_file": "HDRI file",
    "light.environment_intensity": "HDRI intensity", "light.environment_rotation": "HDRI rotation",
    "light.rig_rotation": "rotate all lights",
    "look.exposure": "exposure", "look.background": "background",
    "quality.mode": "accuracy", "quality.supersample": "anti-aliasing", "quality.msaa": "edge samples (MSAA)",
    "quality.render_scale": "resolution", "quality.filter": "thin-fiber filter",
    "quality.filter_width": "filter width", "camera.azimuth": "camera orbit", "camera.elevation": "camera height",
    "camera.distance": "camera distance", "camera.target": "look at", "camera.fov": "field of view",
    "camera.near": "near clip", "camera.far": "far clip",
}

# The method's own words (Zuykov 2015), shown in tooltips so a reader of the thesis finds its terms.
THESIS: dict[str, str] = {
    "scene.count": "guide hairs, one container chain each", "scene.radius": "container (hair cylinder) radius",
    "scene.groom_cluster": "k-means clusters of strands, one container per cluster",
    "scene.segments": "container segments per guide", "scene.taper": "container taper",
    "fibers.rings": "rings: coaxial internal cylinders (thesis 3.3)",
    "fibers.phi_step": "phi step: angle between neighbouring fibers on a ring (thesis 3.4)",
    "fibers.phi_increment": "phi increment per ring inward (thesis 4.3)",
    "fibers.even_spacing": "even spacing: same arc length on every ring (thesis 3.6)",
    "fibers.fiber_radius": "fiber radius, a fraction of the container radius",
    "fibers.edge_density": "clump profile: fibers on the outer rings, a fraction of the inner rings' density",
    "fibers.radial_jitter": "radial jitter (thesis 3.5)", "fibers.angular_jitter": "angular jitter (thesis 3.5)",
    "fibers.length_jitter": "length jitter (thesis 3.7)",
    "fibers.hash": "the per-fiber hash: integer, or the thesis's fract(1207.523 * phi)",
    "shape.ellipsoid": "rings follow the inscribed ellipsoid (thesis Figure 27)",
    "shape.curl_amplitude": "curl (thesis 3.10)", "shape.twist": "twist (thesis 3.10)",
    "quality.mode": "traversal: fast = the thesis's order; exact = nearest hit; brute = every fiber",
}

CHOICE_LABELS: dict[str, dict[str, str]] = {
    "scene.generator": {"single": "one clump", "carpet": "carpet (generated)", "furball": "fur ball (generated)",
                        "curved": "curved carpet (generated)", "groom": "groom file"},
    "fibers.hash": {"integer": "scrambled", "thesis": "thesis (golden-ratio hash)"},
    "look.model": {"kajiya_kay": "Kajiya-Kay (fast)", "marschner": "Marschner (physical)"},
    "look.color_mode": {"rgb": "RGB colour", "melanin": "melanin (as Cycles)"},
    "look.self_shadow": {"off": "off", "density": "estimated", "traced": "traced"},
    "look.color_source": {"look": "the look's colour", "file": "the file's, where it has them"},
    "quality.mode": {"fast": "fast", "exact": "exact", "brute": "reference (slow)"},
    "quality.filter": {"off": "off (one ray)", "coverage": "coverage (holds still)"},
    "light.environment": {"off": "off", "studio": "studio (generated)", "sky": "sky (generated)",
                          "file": "image file"},
}

_GENERATED_ONLY = "a groom file sets it"
# key -> (applies?, why not). Controls that do not apply are hidden; the section says which and why.
APPLIES: dict[str, tuple[Callable[[Params], bool], str]] = {
    "look.color": (lambda p: p["look.color_mode"] == "rgb", "colour comes from melanin"),
    "look.melanin": (lambda p: p["look.color_mode"] == "melanin", "colour comes from RGB"),
    "look.melanin_redness": (lambda p: p["look.color_mode"] == "melanin", "colour comes from RGB"),
    "look.shadow_density": (lambda p: p["look.self_shadow"] != "off", "self-shadowing is off"),
    "look.color_source": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "look.tip_start": (lambda p: p["look.tip_blend"] > 0, "tip blend is 0"),
    "look.tip_color": (lambda p: p["look.tip_blend"] > 0 and p["look.color_mode"] == "rgb",
                       "tip blend is 0 / colour comes from melanin"),
    "look.tip_melanin": (lambda p: p["look.tip_blend"] > 0 and p["look.color_mode"] == "melanin",
                         "tip blend is 0 / colour comes from RGB"),
    "scene.groom_file": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "scene.groom_up": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "scene.groom_scale": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "scene.groom_cluster": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "scene.groom_radius_scale": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "scene.groom_children": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "fibers.edge_width": (lambda p: p["fibers.edge_density"] < 1 or p["fibers.edge_thickness"] < 1,
                          "edge density and thickness are 1"),
    "fibers.groom_auto": (lambda p: p["scene.generator"] == "groom", "not a groom"),
    "scene.count": (lambda p: p["scene.generator"] not in ("single", "groom"), "one clump / a groom file sets it"),
    "scene.radius": (lambda p: p["scene.generator"] != "groom", _GENERATED_ONLY),
    "scene.length": (lambda p: p["scene.generator"] != "groom", _GENERATED_ONLY),
    "scene.bend": (lambda p: p["scene.generator"] != "groom" and p["scene.segments"] > 1,
                   "straight guides (1 segment) / a groom file sets it"),
    "scene.seed": (lambda p: p["scene.generator"] != "single", "one clump is not placed at random"),
    "strand.taper_start": (lambda p: p["strand.tip_width"] < 1, "tip thickness is 1 (no taper)"),
    "shape.curl_frequency": (lambda p: p["shape.curl_amplitude"] > 0 or p["shape.frizz"] > 0,
                             "curl size and frizz are 0"),
    "shape.curl_pattern": (lambda p: p["shape.curl_amplitude"] > 0, "curl size is 0"),
    "shape.noise_frequency": (lambda p: p["shape.noise"] > 0, "fine wiggle is 0"),
    "shape.twist_pattern": (lambda p: p["shape.twist"] != 0, "twist is 0"),
    "light.fill_azimuth": (lambda p: p["light.fill_intensity"] > 0, "the fill is off"),
    "light.fill_elevation": (lambda p: p["light.fill_intensity"] > 0, "the fill is off"),
    "light.fill_color": (lambda p: p["light.fill_intensity"] > 0, "the fill is off"),
    "light.rim_azimuth": (lambda p: p["light.rim_intensity"] > 0, "the rim is off"),
    "light.rim_elevation": (lambda p: p["light.rim_intensity"] > 0, "the rim is off"),
    "light.rim_color": (lambda p: p["light.rim_intensity"] > 0, "the rim is off"),
    "light.environment_file": (lambda p: p["light.environment"] == "file", "no image file chosen"),
    "light.environment_intensity": (lambda p: p["light.environment"] != "off", "the HDRI is off"),
    "light.environment_rotation": (lambda p: p["light.environment"] != "off", "the HDRI is off"),
    "quality.msaa": (lambda p: p["quality.mode"] != "brute", "reference accuracy casts one ray per pixel"),
    "quality.supersample": (lambda p: p["quality.mode"] != "brute", "reference accuracy casts one ray per pixel"),
    "quality.filter": (lambda p: filter_applies(p, p["quality.mode"]),
                       "the filter colours exact mode's frames"),
    "quality.filter_width": (lambda p: filtered(p, p["quality.mode"]), "the filter is off or does not apply"),
}


def label(key: str) -> str:
    return LABELS.get(key) or key.split(".", 1)[1].replace("_", " ")


def choice_label(key: str, value: str) -> str:
    return CHOICE_LABELS.get(key, {}).get(value, value)


def applies(p: Params, key: str) -> tuple[bool, str]:
    rule = APPLIES.get(key)
    if rule is None:
        return True, ""
    try:
        return bool(rule[0](p)), rule[1]
    except KeyError:   # a parameter the rule names was renamed: never hide anything because of it
        return True, ""


def sections() -> list[tuple[str, list[str]]]:
    """SECTIONS with every SPEC key placed: unplaced keys join their group's section, else 'Other'."""
    out = [(title, [k for k in keys if any(p.key == k for p in SPEC)]) for title, keys in SECTIONS]
    placed = {k for _, keys in out for k in keys}
    for p in SPEC:
        if p.key in placed:
            continue
        home = next((i for i, (_, keys) in enumerate(out) if any(k.split(".")[0] == p.group for k in keys)), None)
        if home is None:
            out.append(("Other", []))
            home = len(out) - 1
        out[home][1].append(p.key)
        placed.add(p.key)
    return out
