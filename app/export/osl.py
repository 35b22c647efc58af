"""Export a look as an OSL shader for Blender Cycles: the virtual-fiber traversal, ported from ``glsl/``.

``vfiber export-osl PRESET -o NAME.osl`` writes one self-contained ``.osl`` file: the OSL twin of the GLSL
(:mod:`app.export.osl_source`, section by section) and a parameter block generated from ``app.params.SPEC``
with the preset's values as defaults and ``label``/``min``/``max``/``help`` metadata, so that a Script node in
Blender shows named, bounded inputs. Set-up and what differs from the preview: ``docs/osl.md``.

API
===

``export_osl(params, path, name=None, description="") -> Path``
    Write the shader (atomically). ``name`` (default: the file stem) names the shader ``vfiber_<name>``.
``osl_source(params, name="vfiber", description="") -> str``
    The shader text.
``export_params(params, path, name=None) -> (json_path, block_path)``
    ``--params-only``: the parameter set as JSON (``{"parameters": {osl_name: value}, "keys": {osl_name:
    vfiber key}, "choices": ...}``) and as an OSL parameter block (``NAME.params.osl``).
``osl_parameters(params) -> list[OslParam]`` / ``osl_values(params) -> {osl_name: value}``
    The shader's inputs: every exported SPEC key (``fibers.rings`` -> ``fibers_rings``), string choices as
    ints (``shape.curl_pattern`` "wave" -> 1, with an OSL ``mapper`` widget), then the Cycles-only extras.
``main(argv) -> int``
    The command line (``app/cli.py`` routes ``vfiber export-osl ...`` here); errors are raised as
    ``ParamError``/``UsageError`` (ValueError) for the caller to print as one line.

Decisions
=========

* **Ring layout computed in the shader**, not baked as arrays: the per-ring numbers of
  ``app.fibers.ring_layout`` are a few flops and one hash per ring visit, and computing them from the
  parameters keeps every slider of the Script node live (rings, phi step, jitter...). Baked arrays would
  freeze the layout at export and silently ignore those sliders. The price is float32 instead of float64
  for those numbers; the fiber counts per ring are integers of ``floor(360 / step + 0.5)`` and agree unless
  ``360 / step`` lies within float32 rounding of a half (checked for every bundled preset by the tests),
  and the angular reach of the candidate windows is widened by a few ulps where float32 would narrow it.
* **Metadata**: every input has ``label``, ``min``, ``max`` and ``help`` from SPEC (``int min``/``int max``
  on integer inputs, OSL's convention, so oslquery reports them typed); choices add ``widget = "mapper"``.
  Blender's Script node shows the label on the socket; the rest serves other OSL hosts and pipelines.
* **What is exported**: the container geometry (``scene.radius``, ``scene.length``, ``scene.taper``, in the
  object's units), ``fibers.*``, ``shape.*``, the fiber look (``look.model``, colour or melanin, roughness,
  variations, self-shadow) and ``quality.mode``. Not exported: the camera, the preview's lamp, ambient,
  background and exposure (Cycles lights the scene), supersampling (Cycles samples), scene generators.
* **Closures**: ``look.model = "marschner"`` gives Cycles' Principled Hair (``hair_chiang``) with the
  absorption from melanin exactly as Principled Hair computes it, or from the colour by its "Direct
  coloring"; ``"kajiya_kay"`` gives the preview's lobes (diffuse, white primary and tinted secondary
  highlight) as ``diffuse`` + ``hair_reflection`` on the fiber's own tangent, coloured by the same
  colour (in melanin mode, the colour whose "Direct coloring" absorption is the melanin's).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Sequence

from app.atomic import atomic_write_text
from app.errors import UsageError
from app.params import BY_KEY, Params, with_assignments
from app.scene.grooms import GROOM_SUFFIXES

from . import osl_source as _src
from .osl_strings import osl_comment, osl_identifier, osl_string_literal

__all__ = ["OslParam", "EXPORTED_KEYS", "osl_name", "osl_parameters", "osl_values", "parameter_block",
           "params_json", "shader_name", "osl_source", "export_osl", "export_params",
           "main"]

FORMAT = "vfiber-osl-params"
FORMAT_VERSION = 1

#: the SPEC keys that become shader inputs, in the order the Script node lists them
EXPORTED_KEYS: tuple[str, ...] = (
    "scene.radius", "scene.length", "scene.taper",
    "fibers.rings", "fibers.phi_step", "fibers.phi_increment", "fibers.even_spacing", "fibers.edge_density",
    "fibers.edge_width", "fibers.edge_thickness", "fibers.fiber_radius",
    "fibers.radial_jitter", "fibers.angular_jitter", "fibers.length_jitter", "fibers.hash", "fibers.seed",
    "strand.tip_width", "strand.taper_start",
    "shape.ellipsoid", "shape.curl_amplitude", "shape.curl_frequency", "shape.curl_pattern", "shape.frizz",
    "shape.noise", "shape.noise_frequency", "shape.twist", "shape.twist_pattern",
    "look.model", "look.color_mode", "look.color", "look.melanin", "look.melanin_redness",
    "look.color_source", "look.tip_blend", "look.tip_start", "look.tip_color", "look.tip_melanin", "look.roughness",
    "look.tint_variation", "look.roughness_variation", "look.self_shadow", "look.shadow_density",
    "look.light_azimuth", "look.light_elevation", "look.light_intensity", "look.ambient",
    "quality.mode",
)

#: labels where the bare parameter name would be ambiguous on a node
_LABELS = {
    "scene.radius": "Container radius",
    "scene.length": "Container length",
    "scene.taper": "Container taper",
    "fibers.hash": "Random numbers",
    "fibers.seed": "Fiber seed",
    "look.model": "Shading model",
    "look.color_mode": "Colour from",
    "look.color": "Colour",
    "look.roughness": "Roughness",
    "quality.mode": "Traversal",
}

#: extra help for the shader, where the OSL meaning differs from the preview's
_HELP_NOTES = {
    "scene.radius": "in object units; a mesh attribute vf_radius overrides it per object",
    "scene.length": "in object units; a mesh attribute vf_length overrides it per object",
    "look.self_shadow": "traced leaves shadowing to Cycles",
    "look.color_source": "file: the face attributes vf_root_color / vf_tip_color (export-blend writes them)",
    "look.light_azimuth": "only for the density self-shadow: light the scene with a lamp (export-blend adds one)",
    "look.light_elevation": "only for the density self-shadow: light the scene with a lamp (export-blend adds one)",
    "look.light_intensity": "only weighs the density self-shadow of the key light against the fill's",
    "look.ambient": "only weighs the density self-shadow of the fill against the key light's",
}


@dataclass(frozen=True)
class _Extra:
    name: str
    kind: type
    default: Any
    lo: float
    hi: float
    label: str
    help: str


#: inputs that exist only in the shader (no SPEC key): Principled Hair's own settings, and a debug switch
EXTRAS: tuple[_Extra, ...] = (
    _Extra("cycles_radial_roughness", float, 0.3, 0.0, 1.0, "Radial roughness",
           "Cycles Principled Hair: azimuthal roughness (its default 0.3); also drives the colour-to-absorption "
           "conversion"),
    _Extra("cycles_coat", float, 0.0, 0.0, 1.0, "Coat", "Cycles Principled Hair: coat (marschner model only)"),
    _Extra("cycles_ior", float, 1.55, 1.0, 3.0, "IOR", "Cycles Principled Hair: index of refraction of the "
           "fiber (marschner model only)"),
    _Extra("cycles_offset", float, 2.0, -90.0, 90.0, "Offset",
           "Cycles Principled Hair: tilt of the cuticle scales, degrees (marschner model only)"),
    _Extra("debug_view", int, 0, 0, 1, "Debug view",
           "0 = shaded; 1 = emit the fiber ids as colour (ring, fiber, guide + 1) to check the set-up"),
)

#: outputs besides the closure (for AOVs): whether a fiber was hit, its ring, fiber and guide
OUTPUTS = ("Hit", "Ring", "Fiber", "Guide")


@dataclass(frozen=True)
class OslParam:
    """One shader input."""
    name: str                       # OSL identifier (and Script node socket identifier)
    key: str | None                 # the SPEC key, None for a Cycles-only extra
    type: str                       # "int", "float" or "color"
    value: Any                      # default: int, float, or a 3-tuple for a colour
    label: str
    help: str
    lo: float | None
    hi: float | None
    choices: tuple[str, ...] = ()   # a SPEC string choice exported as its index

    def metadata(self) -> str:
        items = [f'string label = {_osl_string(self.label)}']
        if self.lo is not None and self.hi is not None:
            if self.type == "int":
                items += [f"int min = {int(self.lo)}", f"int max = {int(self.hi)}"]
            else:
                items += [f"float min = {_osl_float(self.lo)}", f"float max = {_osl_float(self.hi)}"]
        if self.choices:
            options = "|".join(f"{c}:{i}" for i, c in enumerate(self.choices))
            items += ['string widget = "mapper"', f"string options = {_osl_string(options)}"]
        items.append(f"string help = {_osl_string(self.help)}")
        return "[[ " + ", ".join(items) + " ]]"

    def declaration(self) -> str:
        """``int fibers_rings = 10 [[ ... ]]`` (no trailing comma)."""
        return f"{self.type} {self.name} = {_osl_value(self.type, self.value)} {self.metadata()}"


# --------------------------------------------------------------------------------------------------------------
# parameters


def osl_name(key: str) -> str:
    """``fibers.rings`` -> ``fibers_rings``: the OSL parameter, socket identifier and JSON name of a key."""
    return key.replace(".", "_")


def _label(key: str) -> str:
    return _LABELS.get(key) or BY_KEY[key].name.replace("_", " ").capitalize()


def _help(key: str) -> str:
    spec = BY_KEY[key]
    text = spec.help
    if spec.unit and spec.unit != "units":   # lengths are in object units: the note says so
        text += f" ({spec.unit})"
    if spec.choices:
        text += ": " + ", ".join(f"{i} = {c}" for i, c in enumerate(spec.choices))
    if key in _HELP_NOTES:
        text += "; " + _HELP_NOTES[key]
    return text


def osl_parameters(params: Params) -> list[OslParam]:
    """The shader's inputs with this look's values as defaults: the exported SPEC keys, then the extras."""
    out: list[OslParam] = []
    for key in EXPORTED_KEYS:
        spec = BY_KEY[key]
        value = params[key]
        if spec.choices:
            out.append(OslParam(osl_name(key), key, "int", spec.choices.index(value), _label(key), _help(key),
                                0, len(spec.choices) - 1, spec.choices))
        elif spec.kind is tuple:
            out.append(OslParam(osl_name(key), key, "color", tuple(float(v) for v in value), _label(key),
                                _help(key), spec.lo, spec.hi))
        elif spec.kind is int:
            out.append(OslParam(osl_name(key), key, "int", int(value), _label(key), _help(key), spec.lo, spec.hi))
        elif spec.kind is float:
            out.append(OslParam(osl_name(key), key, "float", float(value), _label(key), _help(key), spec.lo,
                                spec.hi))
        else:  # pragma: no cover - every exported key is one of the above
            raise TypeError(f"{key}: cannot export a {spec.kind.__name__} parameter to OSL")
    for x in EXTRAS:
        out.append(OslParam(x.name, None, "int" if x.kind is int else "float", x.kind(x.default), x.label,
                            x.help, x.lo, x.hi))
    return out


def osl_values(params: Params) -> dict[str, Any]:
    """``{osl_name: default}``; colours as lists (JSON, and what a Blender socket takes)."""
    return {p.name: (list(p.value) if p.type == "color" else p.value) for p in osl_parameters(params)}


def parameter_block(params: Params, indent: str = "    ") -> str:
    """The shader's parameter declarations, one per line, comma-separated (no closure outputs)."""
    return ",\n".join(indent + p.declaration() for p in osl_parameters(params))


def params_json(params: Params, name: str = "vfiber", description: str = "") -> str:
    """The parameter set for pipelines that already hold the shader: values by OSL parameter name, the
    vfiber key of each, and the integer of every choice."""
    plist = osl_parameters(params)
    doc = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "preset": name,
        "description": description,
        "shader": shader_name(name),
        "parameters": {p.name: (list(p.value) if p.type == "color" else p.value) for p in plist},
        "keys": {p.name: p.key for p in plist if p.key},
        "choices": {p.name: {c: i for i, c in enumerate(p.choices)} for p in plist if p.choices},
    }
    return json.dumps(doc, indent=2) + "\n"


# --------------------------------------------------------------------------------------------------------------
# the shader


def shader_name(name: str) -> str:
    """``vfiber_<name>`` as an OSL identifier."""
    return osl_identifier(f"vfiber_{name}")


def osl_source(params: Params, name: str = "vfiber", description: str = "") -> str:
    """The whole shader for this look."""
    if not isinstance(params, Params):
        raise TypeError(f"osl_source needs Params, not {type(params).__name__}")
    sname = shader_name(name)
    changed = {k: v for k, v in params.differs_from_default().items() if k in EXPORTED_KEYS}
    head = [
        f"// {sname}.osl: virtual fibers in hair cylinders (Zuykov 2015) for Blender Cycles' Script node.",
        "// " + osl_comment(f"Generated by `vfiber export-osl` from the look {name!r}; re-export rather than "
                            "edit."),
    ]
    if description:
        head += _comment_lines(description)
    head += [
        "//",
        "// Set-up (docs/osl.md): `vfiber export-blend` writes a scene whose proxy mesh carries every container",
        "// segment as face attributes (vf_p0 ...). By hand: one mesh object per straight container with its",
        "// origin at the root, local +Z to the tip, radius and length in object units (the Container inputs,",
        "// or mesh attributes vf_radius / vf_length). Where a ray meets no virtual fiber it is transparent().",
        "// The library below is osl/ (a mirror of vfiber's glsl/, function by function), inlined; no trace().",
        *_comment_lines("Changed from vfiber's defaults: " + (", ".join(f"{k} = {_short(v)}"
                                                                       for k, v in changed.items()) or "nothing")),
        "",
        '#include "stdcycles.h"',
    ]
    outputs = ",\n".join(["    output closure color BSDF = 0"]
                         + [f"    output float {o} = {'0' if o == 'Hit' else '-1'}" for o in OUTPUTS])
    meta = (f"[[ string label = {_osl_string('vfiber ' + name)}, string help = "
            f"{_osl_string('Virtual fibers in a hair cylinder (vfiber look ' + repr(name) + ')')} ]]")
    body = [
        "\n".join(head),
        *(section.strip("\n") + "\n" for section in _src.LIBRARY),
        f"shader {sname}\n    {meta}\n(\n{parameter_block(params)},\n{outputs})" + _src.SHADER_BODY,
    ]
    return "\n".join(body)


def export_osl(params: Params, path: str | Path, name: str | None = None, description: str = "") -> Path:
    """Write the shader for ``params`` to ``path`` (atomically: a failure leaves any old file as it was)."""
    path = Path(path)
    _check_folder(path)
    return atomic_write_text(path, osl_source(params, name or path.stem, description))


def export_params(params: Params, path: str | Path, name: str | None = None,
                  description: str = "") -> tuple[Path, Path]:
    """Write ``<stem>.json`` and ``<stem>.params.osl`` beside ``path``; returns both paths."""
    path = Path(path)
    json_path = path if path.suffix.lower() == ".json" else path.with_suffix(".json")
    block_path = json_path.with_suffix(".params.osl")
    _check_folder(json_path)
    name = name or json_path.stem
    title = osl_comment(f"Parameter block of shader {shader_name(name)} (vfiber look {name!r}), generated by "
                        "`vfiber export-osl --params-only`.")
    block = (f"// {title}\n// Paste between the parentheses of the shader declaration; the closure output BSDF "
             f"follows it.\n{parameter_block(params)}\n")
    atomic_write_text(json_path, params_json(params, name, description))
    atomic_write_text(block_path, block)
    return json_path, block_path


# --------------------------------------------------------------------------------------------------------------
# command line


def _usage_error(message: str) -> Exception:
    return UsageError(message)


def _check_folder(path: Path) -> None:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise _usage_error(f"{path}: folder {folder} does not exist")


def make_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="vfiber export-osl",
        description="Write an OSL shader (Blender Cycles Script node) implementing a look's virtual fibers, "
                    "with the look's values as parameter defaults. See docs/osl.md.")
    ap.add_argument("preset", metavar="PRESET", help="bundled preset name or .toml file")
    ap.add_argument("-o", dest="output", metavar="OUT",
                    help="output file (default: PRESET.osl, or PRESET.json with --params-only)")
    ap.add_argument("--params-only", action="store_true",
                    help="write only the parameter set: OUT.json and OUT.params.osl (an OSL parameter block)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a parameter, e.g. --set fibers.rings=20 (repeatable)")
    ap.add_argument("--preset", dest="look", metavar="LOOK", help="with a groom file as PRESET: the shader of "
                    "this preset's look on the groom, as export-blend embeds it (docs/presets.md)")
    return ap


def load_look(target: str, assignments: Sequence[str] = (), look: str | None = None) -> tuple[Params, str, str]:
    """(params, name, description) of a preset plus ``--set`` overrides; ``look`` (``--preset``) on a groom
    as every command takes it (presets.resolve_params, which refuses it on anything but a groom)."""
    from app.presets import find_preset, resolve_params

    if look is not None and look != target:
        params, _ = resolve_params(target, assignments, look=look)
        return params, f"{Path(target).stem}-{Path(look).stem}", f"the look of {look} on {target}"
    preset = find_preset(target)
    params = with_assignments(preset.params.values, assignments)
    name = preset.path.stem if preset.path is not None else preset.name
    return params, name, preset.description


def main(argv: Sequence[str] | None = None) -> int:
    args = make_parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    if Path(args.preset).suffix.lower() in GROOM_SUFFIXES and not args.look:
        raise _usage_error(f"{args.preset} is a groom file: export-osl writes a look's shader for hand-built "
                           f"containers; for the groom's containers use: vfiber export-blend {args.preset} "
                           f"-o {Path(args.preset).stem}.blend (or add --preset LOOK for a look's shader on it)")
    params, name, description = load_look(args.preset, args.set, args.look)
    if args.params_only:
        out = Path(args.output or f"{name}.json")
        json_path, block_path = export_params(params, out, name, description)
        print(f"wrote {json_path} and {block_path}: {len(osl_parameters(params))} parameters of shader "
              f"{shader_name(name)}")
        return 0
    out = Path(args.output or f"{name}.osl")
    if out.suffix.lower() != ".osl":
        raise _usage_error(f"-o {out}: an OSL shader file ends in .osl (use --params-only for .json)")
    export_osl(params, out, name, description)
    print(f"wrote {out}: shader {shader_name(name)} with {len(osl_parameters(params))} parameters; "
          f"load it in a Script node (docs/osl.md)")
    return 0


# --------------------------------------------------------------------------------------------------------------
# formatting


def _osl_float(x: float) -> str:
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x} as an OSL literal")
    text = repr(x)
    return text if any(c in text for c in ".eE") else text + ".0"


def _osl_value(kind: str, value: Any) -> str:
    if kind == "int":
        return str(int(value))
    if kind == "float":
        return _osl_float(value)
    return "color(" + ", ".join(_osl_float(v) for v in value) + ")"


_osl_string = osl_string_literal  # every label, help text and option list goes through the one escaper


def _comment_lines(text: str, width: int = 110) -> list[str]:
    import textwrap

    return ["// " + osl_comment(line) for line in textwrap.wrap(osl_comment(" ".join(text.split())), width - 3)]


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, tuple):
        return "(" + ", ".join(_short(v) for v in value) + ")"
    return repr(value) if isinstance(value, str) else str(value)


if __name__ == "__main__":  # python -m app.export.osl ...: the same one-line errors as `vfiber export-osl`
    from app.cli import main as _cli_main

    sys.exit(_cli_main(["export-osl", *sys.argv[1:]]))
