"""The ``vfiber`` command line: render, turntable, info, doctor, presets, view, bench, export-osl.

Every error a person can cause (a bad preset, a bad ``--set``, a broken groom file, no GL driver, a shader
that does not compile) ends in one line on stderr and exit status 2, never a traceback. ``VFIBER_DEBUG=1``
shows the traceback for developers.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

from .errors import UsageError, VfiberError
from .output import IMAGE_SUFFIXES, OUTPUTS, output_data, output_image, unpremultiplied_rgba, write_output
from .params import ParamError, Params
from .params import parse_assignment as parse_cli_assignment
from .presets import DEFAULT_PRESET, LOOK_GROUPS, groom_relative_to_preset, is_groom, resolve_params
from .scene.grooms import GROOM_SUFFIXES
from .units import parse_bytes, parse_size

# Names other code and older scripts import from here; they live where the layer below can reach them.
__all__ = ["DEFAULT_PRESET", "GROOM_SUFFIXES", "IMAGE_SUFFIXES", "OUTPUTS", "UsageError", "groom_relative_to_preset",
           "main", "output_data", "output_image", "parse_cli_assignment", "parse_size", "resolve_params",
           "unpremultiplied_rgba", "write_output"]


# --------------------------------------------------------------------------------------------------
# parameters from the command line
# --------------------------------------------------------------------------------------------------
def target_params(args) -> tuple[Params, str]:
    """The parameters of the positional target with ``--preset``'s look on it when the target is a groom
    (alone, --preset is the target), then ``--set``; see presets.resolve_params. Never silently drops one."""
    return resolve_params(args.target, args.set, look=args.preset)


def source_of(key: str | None, assignments: list[str], label: str) -> str:
    """Where a parameter came from, for errors raised after Params were built (the renderer's)."""
    if key and any(a.split("=", 1)[0].strip() == key for a in assignments):
        return "--set"
    return label


def check_output_path(out: Path) -> None:
    """Before any work: the output's folder exists and the file may be replaced (not a folder, not
    read-only), so a long render never ends in 'cannot write'."""
    from .atomic import SaveError, save_target

    if out.suffix.lower() not in IMAGE_SUFFIXES:
        raise UsageError(f"{out}: unknown image type {out.suffix.lower()!r}; use .png, .exr or .npy")
    try:
        save_target(out)
    except SaveError as e:
        raise UsageError(f"-o {e}") from None


def check_budget(p: Params, size: tuple[int, int], allow_slow: bool, scene=None):
    """Refuse, with the estimate and how to go on, work that would take minutes or more memory than a
    frame should; before the scene is built (scene None) only its build and the frame's memory are known.
    Returns the frame's WorkEstimate once the scene is given."""
    from .render import budget
    from .units import human_bytes

    how = "add --allow-slow to run it anyway"
    if scene is None:
        seconds = budget.build_seconds(p)
        if seconds > budget.SLOW_SECONDS and not allow_slow:
            if p["scene.generator"] == "groom":
                raise UsageError(f"clustering the groom's strands into scene.groom_cluster = "
                                 f"{p['scene.groom_cluster']:,} guides takes roughly {budget._duration(seconds)} "
                                 f"before the first pixel; ask for fewer guides (or 0: one per strand), or {how}")
            raise UsageError(f"building {p['scene.count']:,} guides x {p['scene.segments']} segments takes roughly "
                             f"{budget._duration(seconds)} before the first pixel; lower scene.count or "
                             f"scene.segments, or {how}")
        need = budget.frame_bytes(size)
        if need > budget.MAX_FRAME_BYTES and not allow_slow:
            raise UsageError(f"--size {size[0]}x{size[1]} needs about {human_bytes(need)} of memory for one frame "
                             f"(limit {human_bytes(budget.MAX_FRAME_BYTES)}); render smaller, or {how}")
        return None
    est = budget.estimate(p, scene, size)
    if est.slow and not allow_slow:
        raise UsageError(f"this frame is {est.summary()}; lower the image size, quality.supersample or the "
                         f"fiber density, or {how}")
    return est


def _gl_allocation_error(e: Exception, size: tuple[int, int]) -> UsageError | None:
    text = str(e)
    if isinstance(e, UsageError):
        return None
    if "framebuffer" in text.lower() or "out of memory" in text.lower() or isinstance(e, MemoryError):
        return UsageError(f"--size {size[0]}x{size[1]}: this OpenGL cannot allocate a frame that large "
                          f"({text.strip().splitlines()[0] if text.strip() else type(e).__name__}); render smaller")
    return None


# --------------------------------------------------------------------------------------------------
# commands
# --------------------------------------------------------------------------------------------------
def build_scene_for(p: Params):
    from .scene.generators import build_scene

    return build_scene(p)


def cmd_render(args) -> int:
    if args.variant:
        return cmd_contact_sheet(args)
    p, label = target_params(args)
    if args.mode:
        p = p.replace(**{"quality.mode": args.mode})
    size = parse_size(args.size)
    out = Path(args.output_file)
    if not out.parent.exists():
        raise UsageError(f"{out}: folder {out.parent} does not exist")
    check_output_path(out)
    kind = args.output
    if args.alpha and kind != "shaded":
        raise UsageError(f"--alpha writes the shaded picture's coverage; --output {kind} has no alpha")
    if args.alpha and out.suffix.lower() in (".jpg", ".jpeg", ".bmp"):
        raise UsageError(f"{out}: {out.suffix} has no alpha channel; use .png, .tif or .exr with --alpha")
    if args.alpha and args.method == "explicit":
        raise UsageError("--alpha needs the virtual method's coverage; the explicit baseline has none")
    t0 = time.perf_counter()
    check_budget(p, size, args.allow_slow)
    scene = build_scene_for(p)
    est = check_budget(p, size, args.allow_slow, scene) if args.method == "virtual" else None
    if est is not None and est.seconds > LONG_RENDER_S:
        print(f"vfiber: rendering {out.name}: {est.summary()}", file=sys.stderr, flush=True)

    def render() -> int:
        try:
            return _render_and_write(args, p, label, size, out, kind, scene, t0)
        except ParamError as e:  # the renderer's (quality.msaa the driver cannot do): say where it came from
            if e.source is None:
                raise ParamError(e.bare, key=e.key, source=source_of(e.key, args.set, label)) from None
            raise
        except Exception as e:  # noqa: BLE001 - a frame GL cannot allocate is a size problem, said so
            better = _gl_allocation_error(e, size)
            if better is None:
                raise
            raise better from None

    if _interactive():
        return _in_child(render, out)
    try:
        # Not at a terminal: Ctrl-C raises KeyboardInterrupt once the GL driver returns; the output is
        # written whole or not at all (app.atomic), so nothing partial stays either way.
        return render()
    except KeyboardInterrupt:
        print(f"vfiber: interrupted: {out} was not written", file=sys.stderr)
        return 130


def _interactive() -> bool:
    """At a terminal, where Ctrl-C is how a person stops a render (and where nothing captures sys.stdout)."""
    try:
        return hasattr(os, "fork") and sys.stdin.isatty() and not os.environ.get("VFIBER_NO_FORK")
    except (ValueError, OSError):
        return False


def _in_child(render, out: Path) -> int:
    """Run ``render`` in a forked child and wait for it. moderngl holds the GIL while llvmpipe draws, so a
    KeyboardInterrupt in the rendering process would wait for the whole frame; the waiting parent gets it
    at once, kills the child and removes its temporary file: Ctrl-C stops cleanly, with no output."""
    import signal

    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the child: Ctrl-C is the parent's to handle
        code = 2
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            code = render()
        except BaseException as e:  # noqa: BLE001 - the child reports like main() and exits
            if os.environ.get("VFIBER_DEBUG"):
                import traceback
                traceback.print_exc()
            else:
                print(f"vfiber: {describe_error(e)}", file=sys.stderr)
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    try:
        _, status = os.waitpid(pid, 0)
    except KeyboardInterrupt:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        from .atomic import remove_stale_temporaries
        remove_stale_temporaries(out)
        print(f"\nvfiber: interrupted: {out} was not written", file=sys.stderr)
        return 130
    code = os.waitstatus_to_exitcode(status)
    if code < 0:
        print(f"vfiber: the render process died of signal {-code} (a GL driver crash?); {out} was not written; "
              "run vfiber doctor", file=sys.stderr)
        return 2
    return code


LONG_RENDER_S = 5.0  # renders estimated longer than this announce themselves with the estimate


def _render_and_write(args, p, label, size, out, kind, scene, t0) -> int:
    from .gl.context import create_headless
    from .render.camera import Camera
    from .render.renderer import Renderer
    from .render.tiled import TILED_ABOVE_PIXELS, print_progress, render_tiled

    wanted = {"shaded": ("color",), "id": ("ids",), "ring": ("ids",), "depth": ("geom",),
              "normal": ("geom",), "cost": ("cost",)}[kind]
    with create_headless() as gl:
        cam = Camera.from_params(p, scene, size[0] / size[1])
        if args.method == "explicit":
            # the conventional baseline: every fiber stored in GPU buffers and rasterized
            from .render.explicit import ExplicitBudgetError, ExplicitRenderer

            if kind == "cost":
                raise UsageError("--output cost counts fiber tests of the virtual method; the explicit method "
                                 "rasterizes and has none")
            explicit = (ExplicitRenderer(gl.ctx, budget_bytes=args.explicit_budget) if args.explicit_budget
                        else ExplicitRenderer(gl.ctx))
            try:
                stats = explicit.set_scene(scene, p)
            except ExplicitBudgetError as e:   # name the option a command-line user has, not the API
                raise UsageError(budget_message(e)) from None
            frame = explicit.render(p, cam, size, outputs=wanted)
            what = f"{stats.fibers} explicit fibers in {explicit.gpu_bytes} GPU bytes"
        else:
            renderer = Renderer(gl.ctx)
            renderer.set_scene(scene)
            if size[0] * size[1] * p["quality.render_scale"] ** 2 > TILED_ABOVE_PIXELS:
                frame = render_tiled(renderer, p, cam, size, outputs=wanted, progress=print_progress(sys.stderr))
                print(f"writing {out} ...", file=sys.stderr, flush=True)   # compressing 64 Mpix takes a while
            else:
                frame = renderer.render_quality(p, cam, size, outputs=wanted)
            what = f"{scene.n_segments} container segments in {renderer.scene_gpu_bytes} GPU bytes"
        write_output(out, frame, kind, p, alpha=args.alpha)
        seconds = time.perf_counter() - t0
        alpha = ", alpha = coverage" if args.alpha else ""
        print(f"wrote {out} ({kind}{alpha}, {size[0]}x{size[1]}, {args.method} method, {p['quality.mode']} mode) "
              f"from {label}: {what}, {seconds:.2f} s on {gl.renderer}")
    return 0


def budget_message(e) -> str:
    """The explicit method's refusal in command-line words: the option to raise, with a value that fits."""
    from .units import human_bytes

    fits = 2 ** math.ceil(math.log2(max(e.needed, 1)))
    text = str(e).replace("(ExplicitRenderer(ctx, budget_bytes=...))",
                          f"(--explicit-budget {human_bytes(fits).replace(' ', '').replace('.0', '')})")
    return text


def cmd_contact_sheet(args) -> int:
    """``vfiber render TARGET --variant ... -o sheet.png``: one labelled tile per look."""
    from .contact_sheet import parse_variants, render_contact_sheet

    if args.output != "shaded" or args.method != "virtual":
        raise UsageError("--variant makes a contact sheet of shaded virtual renders; leave out --output/--method")
    out = Path(args.output_file)
    if not out.parent.exists():
        raise UsageError(f"{out}: folder {out.parent} does not exist")
    base_target, base_look = (args.target, args.preset) if args.target else (args.preset, None)
    base, _ = resolve_params(base_target, args.set, look=base_look)   # a bad target fails before any tile
    on_groom = is_groom(base)

    def resolve_variant(target: str | None, sets: list[str]) -> tuple[Params, str]:
        """On a groom TARGET a variant's preset is a look on the groom (the groom's strands and camera stay,
        see presets.LOOK_GROUPS); a variant groom, or any variant of a generated TARGET, is its own scene."""
        if target == base_target:
            return resolve_params(base_target, sets, look=base_look)
        if on_groom and target is not None and Path(target).suffix.lower() not in GROOM_SUFFIXES:
            return resolve_params(base_target, sets, look=target)
        return resolve_params(target, sets)

    looks = parse_variants(base_target, args.set, args.variant, resolve_variant, args.mode)
    t0 = time.perf_counter()
    sheet = render_contact_sheet(looks, parse_size(args.size), out,
                                 progress=lambda n, total, label: print(f"rendering {n}/{total}: {label}",
                                                                        file=sys.stderr, flush=True))
    print(f"wrote {out} (contact sheet of {len(looks)} looks, {sheet.size[0]}x{sheet.size[1]}), "
          f"{time.perf_counter() - t0:.2f} s")
    return 0


def cmd_turntable(args) -> int:
    from .turntable import render_turntable

    p, label = target_params(args)
    if args.mode:
        p = p.replace(**{"quality.mode": args.mode})
    if args.filter:
        p = p.replace(**{"quality.filter": args.filter})
    if args.frames < 1 or args.frames > 3600:
        raise UsageError(f"--frames {args.frames}: between 1 and 3600")
    out = Path(args.output_dir)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{out} is a file; -o names a folder for the frames")
    if not out.parent.exists():
        raise UsageError(f"{out}: folder {out.parent} does not exist")
    t0 = time.perf_counter()

    def progress(n: int, total: int, path: Path) -> None:
        left = (time.perf_counter() - t0) / n * (total - n)
        print(f"frame {n}/{total}: {path.name} (about {left:.0f} s left)", file=sys.stderr, flush=True)

    result = render_turntable(p, out, frames=args.frames, size=parse_size(args.size), alpha=args.alpha,
                              degrees=args.degrees, video=not args.no_video, light=args.light,
                              progress=progress)
    video = f"; video {result.video}" if result.video else f"; no video ({result.video_note})"
    print(f"wrote {len(result.frames)} frames to {out}/ from {label}{video}, {time.perf_counter() - t0:.1f} s")
    return 0


def cmd_info(args) -> int:
    from .info import info_lines

    p, label = target_params(args)
    for line in info_lines(p, build_scene_for(p), label):
        print(line)
    return 0


def cmd_doctor(args) -> int:
    from .doctor import main as doctor_main

    return doctor_main()


def cmd_presets(args) -> int:
    from .presets import bundled_presets

    presets = bundled_presets()
    if not presets:
        print("no bundled presets found")
        return 1
    width = max(len(p.name) for p in presets)
    for preset in presets:
        print(f"{preset.name:<{width}}  {preset.description}")
    return 0


def cmd_view(args) -> int:
    from .viewer.app import run_viewer

    overrides = {}
    if args.set or args.preset:   # a bad look or --set fails here, in one line, before a window opens
        resolve_params(args.target, args.set, look=args.preset)
        overrides = dict(parse_cli_assignment(text) for text in args.set)
    target, look = (args.target, args.preset) if args.target else (args.preset, None)
    return run_viewer(target, script=args.script, size=parse_size(args.size), overrides=overrides, look=look)


def cmd_bench(args) -> int:
    from .bench.__main__ import main as bench_main

    return bench_main(args.rest)


def cmd_export_osl(args) -> int:
    from .export.osl import main as export_main

    return export_main(args.rest)


def version() -> str:
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    try:
        return dist_version("vfiber")
    except PackageNotFoundError:   # run from a checkout that was never installed
        return "unknown (not installed)"


def cmd_export_blend(args) -> int:
    from .export.blend import main as export_main

    return export_main(args.rest)


def make_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="vfiber", description="Hair and fur lookdev with virtual fibers.")
    ap.add_argument("--version", action="version", version=f"vfiber {version()}")
    sub = ap.add_subparsers(dest="command", required=True)

    def scene_args(sp):
        sp.add_argument("target", nargs="?", help="preset name or .toml file, or a groom file "
                        f"({' '.join(GROOM_SUFFIXES)})")
        sp.add_argument("--preset", help="preset name or file; alone it is the target. With a groom TARGET it "
                        f"is a look: the preset's {', '.join(g + '.*' for g in LOOK_GROUPS)} go onto the groom, "
                        "which keeps its own scene.*, camera.* and quality.* (docs/presets.md)")
        sp.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a parameter, e.g. --set fibers.rings=20 (repeatable)")

    r = sub.add_parser("render", help="render one frame offscreen to an image")
    scene_args(r)
    r.add_argument("--mode", choices=("fast", "exact", "brute"))
    r.add_argument("--size", default="640x360", help="WIDTHxHEIGHT (default 640x360)")
    r.add_argument("--output", choices=OUTPUTS, default="shaded", help="what to write (default shaded)")
    r.add_argument("-o", dest="output_file", required=True, help="output file: .png, .exr or .npy")
    r.add_argument("--method", choices=("virtual", "explicit"), default="virtual",
                   help="virtual fibers in containers (default) or the conventional explicit strands")
    r.add_argument("--allow-slow", action="store_true",
                   help="render even when the estimate says the frame takes over a minute or over 4 GiB")
    r.add_argument("--explicit-budget", type=parse_bytes, default=None, metavar="BYTES",
                   help="GPU bytes the explicit method may use before it refuses (default 1GiB)")
    r.add_argument("--alpha", action="store_true",
                   help="shaded PNG/TIFF as RGBA with the fibers' coverage as alpha (EXR/NPY: premultiplied)")
    r.add_argument("--variant", action="append", default=[], metavar="LOOK",
                   help="write a labelled contact sheet, one tile per --variant: a preset or groom and/or "
                        "key=value changes on top of TARGET, e.g. --variant curly-1 --variant "
                        "'look.model=marschner look.roughness=0.2' (repeatable); on a groom TARGET a preset "
                        "is a look on the groom, as --preset")
    r.set_defaults(func=cmd_render)

    t = sub.add_parser("turntable", help="render the camera orbiting the hair: a PNG sequence (and a video "
                       "where ffmpeg is installed)")
    scene_args(t)
    t.add_argument("-o", dest="output_dir", required=True, help="folder for frame_0000.png, ...")
    t.add_argument("--frames", type=int, default=36, help="frames per full turn (default 36)")
    t.add_argument("--degrees", type=float, default=360.0, help="how far the camera turns (default 360)")
    t.add_argument("--size", default="640x360", help="WIDTHxHEIGHT (default 640x360)")
    t.add_argument("--mode", choices=("fast", "exact", "brute"))
    t.add_argument("--filter", choices=("off", "coverage"),
                   help="quality.filter (default coverage): coverage keeps thin fibers from shimmering as the "
                        "camera turns, off draws one ray a pixel (docs/antialias.md)")
    t.add_argument("--alpha", action="store_true", help="RGBA frames, coverage as alpha")
    t.add_argument("--no-video", action="store_true", help="frames only, even where ffmpeg is installed")
    t.add_argument("--light", action="store_true", help="turn the lights (light.rig_rotation), not the camera")
    t.set_defaults(func=cmd_turntable)

    i = sub.add_parser("info", help="containers, fibers and GPU bytes of a preset or groom")
    scene_args(i)
    i.set_defaults(func=cmd_info)

    sub.add_parser("doctor", help="check the OpenGL set-up").set_defaults(func=cmd_doctor)
    sub.add_parser("presets", help="list the bundled presets").set_defaults(func=cmd_presets)

    v = sub.add_parser("view", help="open the lookdev viewer")
    scene_args(v)
    v.add_argument("--script", help="run a viewer script (automated sessions and tests)")
    v.add_argument("--size", default="1280x720", help="window size WIDTHxHEIGHT (default 1280x720)")
    v.set_defaults(func=cmd_view)

    b = sub.add_parser("bench", help="run the benchmark suites (see: vfiber bench --help)", add_help=False)
    b.add_argument("rest", nargs=argparse.REMAINDER)
    b.set_defaults(func=cmd_bench)

    e = sub.add_parser("export-osl", help="export a preset as an OSL shader (see: vfiber export-osl --help)",
                       add_help=False)
    e.add_argument("rest", nargs=argparse.REMAINDER)
    e.set_defaults(func=cmd_export_osl)

    eb = sub.add_parser("export-blend", help="export a preset or groom as a .blend for Cycles (see: vfiber "
                        "export-blend --help)", add_help=False)
    eb.add_argument("rest", nargs=argparse.REMAINDER)
    eb.set_defaults(func=cmd_export_blend)
    return ap


# these parse their own options
PASS_THROUGH = {"bench": cmd_bench, "export-osl": cmd_export_osl, "export-blend": cmd_export_blend}


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in PASS_THROUGH:
        args = argparse.Namespace(func=PASS_THROUGH[argv[0]], rest=argv[1:])
    else:
        args = make_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("vfiber: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - the one place that turns errors into messages
        if os.environ.get("VFIBER_DEBUG"):
            raise
        print(f"vfiber: {describe_error(e)}", file=sys.stderr)
        return 2


def describe_error(e: Exception) -> str:
    """One line for a person; unexpected errors say so and how to see the details."""
    if isinstance(e, (VfiberError, FileNotFoundError, PermissionError)):
        return str(e)
    return f"unexpected error: {type(e).__name__}: {e} (run with VFIBER_DEBUG=1 for the traceback)"


if __name__ == "__main__":
    sys.exit(main())
