"""The figures of docs/osl.md (export-blend against the preview) and docs/benchmarks.md (Blender half).

    python -m app.export.figures agreement [--size 192x108] [--out docs/img]   every preset and 3 grooms
    python -m app.export.figures harolongo                                    export and render cost

Each scene is exported with ``vfiber export-blend``, rendered by ``app/export/render_blend.py`` (a process
that imports only bpy, as a farm would) and compared with ``vfiber render`` at the same size:

* coverage: Cycles alpha > 0.5 against the GL hit mask, over all pixels;
* ids: the shader's debug view (one ray per pixel centre) against ``--output id`` on pixels both cover;
* colour: the file's own lighting (key light, world fill) at 32 samples, through the preview's tone map
  (exposure, Reinhard, gamma 2.2), against the preview's shaded image, mean |difference| in 8-bit sRGB
  levels over pixels both cover fully.

A contact sheet per scene (preview | Cycles | |difference| x4) goes to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
HAIR = ROOT.parent / "shared" / "hair-data"
GROOMS = ("sintel_hair.tfx", "Bangs_100.hair", "Ratboy_mohawk.tfx")


def _run(argv: list[str], **kw) -> subprocess.CompletedProcess:
    proc = subprocess.run(argv, capture_output=True, text=True, **kw)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv[:4])} ...: {(proc.stdout + proc.stderr)[-1500:]}")
    return proc


def export(target: str, out: Path, size: str) -> tuple[float, str]:
    code = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"
    t = time.perf_counter()
    proc = _run([sys.executable, "-c", code, "export-blend", target, "-o", str(out), "--size", size], cwd=str(ROOT))
    return time.perf_counter() - t, proc.stdout.strip()


def render(blend: Path, out: Path, *extra: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = _run(["/usr/bin/time", "-v", sys.executable, "-I", str(ROOT / "app/export/render_blend.py"), str(blend),
                 str(out), *extra], cwd=str(out.parent), env=env)
    info = json.loads([ln for ln in proc.stdout.splitlines() if ln.startswith("{")][-1])
    for ln in proc.stderr.splitlines():
        if "Maximum resident set size" in ln:
            info["max_rss_bytes"] = int(ln.split(":")[1]) * 1024
    return info


def preview(target: str, out: Path, size: str, kind: str) -> np.ndarray:
    from app import cli

    assert cli.main(["render", target, "--size", size, "--output", kind, "-o", str(out)]) == 0
    return np.load(out)


def tone_map(linear: np.ndarray, exposure: float) -> np.ndarray:
    """glsl/shading/light.glsl: tone_map, to 8-bit levels."""
    c = linear * 2.0 ** exposure
    c = c / (1.0 + c)
    return np.clip(c, 0, 1) ** (1 / 2.2) * 255.0


def agreement_row(name: str, target: str, size: str, work: Path, sheet_dir: Path | None, direct: bool = True) -> dict:
    from app.cli import resolve_params

    p, _ = resolve_params(target, [])
    blend = work / f"{name}.blend"
    export_s, said = export(target, blend, size)
    ids = render(blend, work / f"{name}_ids.npy", "--ids")
    shaded = render(blend, work / f"{name}_shaded.npy", "--samples", "32", *(["--direct-only"] if direct else []))
    c_ids, c_rgb = np.load(work / f"{name}_ids.npy"), np.load(work / f"{name}_shaded.npy")
    g_ids = preview(target, work / f"{name}_gl_ids.npy", size, "id")
    g_rgb = preview(target, work / f"{name}_gl_rgb.npy", size, "shaded")
    cov_c, cov_g = c_ids[..., 3] > 0.5, g_ids[..., 0] > 0
    both = cov_c & cov_g
    same = (np.rint(c_ids[..., [2, 0, 1]]).astype(np.int64)[both] == g_ids[..., :3][both].astype(np.int64)).all(1)
    alpha = c_rgb[..., 3:4]
    cycles_levels = tone_map(c_rgb[..., :3] / np.maximum(alpha, 1e-6), p["look.exposure"])
    gl_levels = g_rgb[..., :3] * 255.0
    solid = (alpha[..., 0] > 0.99) & cov_g
    diff = np.abs(cycles_levels - gl_levels)
    row = {"name": name, "segments": int(said.split(" container segments")[0].split()[-1]),
           "coverage": float((cov_c == cov_g).mean()), "same_id": float(same.mean()) if both.any() else 1.0,
           "covered": int(both.sum()), "colour_diff": float(diff[solid].mean()) if solid.any() else float("nan"),
           "colour_bias": [float(x) for x in (cycles_levels[solid] - gl_levels[solid]).mean(0)] if solid.any() else [],
           "export_s": export_s, "ids_s": ids["seconds"], "shaded_s": shaded["seconds"],
           "peak_mib": shaded.get("max_rss_bytes", shaded["peak_rss_bytes"]) / 2**20,
           "blend_mb": blend.stat().st_size / 1e6}
    if sheet_dir is not None:
        from PIL import Image

        back = np.array(p["look.background"], np.float64)
        over = cycles_levels * alpha + tone_map(back, p["look.exposure"]) * (1 - alpha)
        d = np.clip(np.abs(over - gl_levels) * 4, 0, 255)
        sheet = np.concatenate([gl_levels, over, d], 1).astype(np.uint8)
        Image.fromarray(sheet).save(sheet_dir / f"blend_vs_preview_{name}.png")
    return row


def cmd_agreement(a) -> int:
    from app.presets import bundled_presets

    targets = [(pr.name, pr.name) for pr in bundled_presets()]
    targets += [(Path(g).stem, str(HAIR / g)) for g in GROOMS if (HAIR / g).exists()]
    if a.only:
        targets = [t for t in targets if t[0] in a.only]
    out = Path(a.out) if a.out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="vfiber-figures-") as d:
        for name, target in targets:
            row = agreement_row(name, target, a.size, Path(d), out)
            rows.append(row)
            print(json.dumps(row), flush=True)
    print("\n| scene | segments | coverage agreement | same (guide, ring, fiber) | colour |diff| (levels) | "
          "bias R, G, B | export | Cycles ids / 32 spp | peak RSS |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        bias = ", ".join(f"{b:+.0f}" for b in r["colour_bias"])
        print(f"| {r['name']} | {r['segments']} | {r['coverage']:.2%} | {r['same_id']:.2%} | "
              f"{r['colour_diff']:.1f} | {bias} | {r['export_s']:.1f} s | "
              f"{r['ids_s']:.1f} s / {r['shaded_s']:.1f} s | {r['peak_mib']:.0f} MiB |")
    return 0


def cmd_harolongo(a) -> int:
    target = str(HAIR / "harolongo.data")
    with tempfile.TemporaryDirectory(prefix="vfiber-haro-") as d:
        blend = Path(d) / "harolongo.blend"
        t = time.perf_counter()
        proc = _run(["/usr/bin/time", "-v", sys.executable, "-c",
                     "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))", "export-blend", target,
                     "-o", str(blend), "--size", a.size], cwd=str(ROOT))
        export_s = time.perf_counter() - t
        rss = [int(ln.split(":")[1]) * 1024 for ln in proc.stderr.splitlines() if "Maximum resident" in ln]
        info = render(blend, Path(d) / "haro.npy", "--samples", str(a.samples))
        print(json.dumps({"export_s": export_s, "export_rss_bytes": rss[0] if rss else None,
                          "blend_bytes": blend.stat().st_size, "said": proc.stdout.strip(), **info}))
    return 0


# ------------------------------------------------------------------------------------------- Table 2
# The thesis's Table 2 in today's Blender: one groom in Cycles as explicit curves (the file's strands, as
# the guides vfiber resamples them, plus child strands scattered in each guide's container) and as the
# exported virtual fibers, at the same fiber count, camera, light, size and samples. One process per row
# (peak memory is the process's); explicit rows whose estimate passes the budget are not run.

EXPLICIT_POINTS = 8          # points per explicit strand (the guides' segments + 1 for the default groom)


def _fiber_params(target: str, fibers: int):
    """Params whose exact fiber count is close to ``fibers`` for the groom: rings and phi_step chosen."""
    from app.fibers import ring_layout
    from app.cli import resolve_params
    from app.scene.generators import build_scene

    p, _ = resolve_params(target, [])
    guides = build_scene(p).n_guides
    per = max(1, fibers / guides)
    best = None
    for rings in range(1, 65):
        # fibers per ring about 360 / phi_step on every ring (even spacing off, no increment)
        step = 360.0 * rings / per
        if not (0.05 <= step <= 180.0):
            continue
        q = p.replace(**{"fibers.rings": rings, "fibers.phi_step": step, "fibers.phi_increment": 0.0,
                         "fibers.even_spacing": 0.0, "fibers.fiber_radius": min(0.45 / rings, 0.02)})
        n = ring_layout(q).fibers_per_container * guides
        if best is None or abs(n - fibers) < abs(best[1] - fibers):
            best = (q, n)
    return best


def _explicit_curves(bpy, scene_data, fibers: int, fiber_radius_units: float, seed: int = 0):
    """Curves object: each guide polyline (its segments' end points) plus children offset in its container."""
    seg = scene_data.segments.astype(np.float64)
    guides = seg[:, 19].astype(np.int64)
    order = np.argsort(guides, kind="stable")
    seg = seg[order]
    starts = np.flatnonzero(np.r_[True, np.diff(seg[:, 19]) != 0])
    polylines, frames, radii = [], [], []
    for a, b in zip(starts, list(starts[1:]) + [len(seg)]):
        pts = np.vstack([seg[a:b, 0:3], seg[b - 1, 4:7]])
        t = np.linspace(0, 1, EXPLICIT_POINTS)
        s = np.linspace(0, 1, len(pts))
        polylines.append(np.stack([np.interp(t, s, pts[:, k]) for k in range(3)], 1))
        ex = seg[a, 16:19]
        ez = (seg[a, 4:7] - seg[a, 0:3]) / np.linalg.norm(seg[a, 4:7] - seg[a, 0:3])
        frames.append((ex, np.cross(ez, ex)))
        radii.append(np.interp(t, s, np.r_[seg[a:b, 3], seg[b - 1, 7]]))
    n_guides = len(polylines)
    per = max(1, int(round(fibers / n_guides)))
    rng = np.random.default_rng(seed)
    total = per * n_guides
    pos = np.empty((total, EXPLICIT_POINTS, 3), np.float32)
    for g, (poly, (ex, ey), rad) in enumerate(zip(polylines, frames, radii)):
        r = np.sqrt(rng.uniform(0, 1, per)) * 0.95
        a = rng.uniform(0, 2 * np.pi, per)
        r[0] = 0.0                                   # the file's strand itself
        off = (r * np.cos(a))[:, None, None] * ex + (r * np.sin(a))[:, None, None] * ey
        pos[g * per:(g + 1) * per] = poly[None] + off * rad[None, :, None]
    curves = bpy.data.hair_curves.new("explicit fibers")
    curves.add_curves([EXPLICIT_POINTS] * total)
    curves.position_data.foreach_set("vector", pos.ravel())
    rad_attr = curves.attributes.get("radius") or curves.attributes.new("radius", "FLOAT", "POINT")
    rad_attr.data.foreach_set("value", np.full(total * EXPLICIT_POINTS, fiber_radius_units, np.float32))
    return curves, total


def cmd_table2_row(a) -> int:
    import resource

    from app.export.blend import export_blend

    from . import blender as B

    q, n = _fiber_params(a.target, a.fibers)
    t0 = time.perf_counter()
    bpy, _ = B._bpy()
    blend = Path(a.work) / f"t2_{a.kind}_{a.fibers}.blend"
    export_blend(q, blend, tuple(int(v) for v in a.size.split("x")), "table2", progress=None)
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    fibers = n
    if a.kind == "explicit":
        from app.scene.generators import build_scene

        sd = build_scene(q)
        for ob in [o for o in bpy.data.objects if o.name.startswith("vfiber_containers")]:
            bpy.data.objects.remove(ob)     # every slot-count group of prisms (blend.NEIGHBOUR_SLOTS)
        rf = q["fibers.fiber_radius"] * float(np.median(sd.segments[:, 3]))
        curves, fibers = _explicit_curves(bpy, sd, n, rf)
        mat = bpy.data.materials.new("explicit hair")
        nt = mat.node_tree
        bsdf = next(x for x in nt.nodes if x.bl_idname == "ShaderNodeBsdfPrincipled")
        nt.nodes.remove(bsdf)
        hair = nt.nodes.new("ShaderNodeBsdfHairPrincipled")
        nt.links.new(hair.outputs[0], next(x for x in nt.nodes if x.bl_idname == "ShaderNodeOutputMaterial").inputs[0])
        curves.materials.append(mat)
        obc = bpy.data.objects.new("explicit fibers", curves)
        obc.location = tuple(float(v) for v in sd.origin)
        scene.collection.objects.link(obc)
        scene.cycles.shading_system = False
    build_s = time.perf_counter() - t0
    scene.cycles.samples = a.samples
    scene.cycles.use_adaptive_sampling = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = str(Path(a.work) / f"t2_{a.kind}_{a.fibers}.png")
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    render_s = time.perf_counter() - t
    print(json.dumps({"kind": a.kind, "fibers": int(fibers), "target": a.fibers, "build_s": build_s,
                      "render_s": render_s,
                      "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}), flush=True)
    os._exit(0)


def cmd_table2(a) -> int:
    rows = []
    with tempfile.TemporaryDirectory(prefix="vfiber-t2-") as d:
        for fibers in a.fibers:
            for kind in ("virtual", "explicit"):
                estimate = 390e6 + 1.6e3 * fibers     # explicit Cycles curves, measured before (issue 14)
                if kind == "explicit" and estimate > a.budget:
                    rows.append({"kind": kind, "fibers": fibers, "skipped": f"estimate {estimate / 2**30:.1f} GiB "
                                 f"> budget {a.budget / 2**30:.1f} GiB"})
                    print(json.dumps(rows[-1]), flush=True)
                    continue
                proc = subprocess.run([sys.executable, "-m", "app.export.figures", "table2-row", "--kind", kind,
                                       "--fibers", str(fibers), "--target", a.target, "--size", a.size,
                                       "--samples", str(a.samples), "--work", d],
                                      capture_output=True, text=True, cwd=str(ROOT), timeout=a.timeout)
                line = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
                row = json.loads(line[-1]) if line else {"kind": kind, "fibers": fibers,
                                                         "error": (proc.stderr or proc.stdout)[-300:]}
                rows.append(row)
                print(json.dumps(row), flush=True)
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for kind, style in (("virtual", "o-"), ("explicit", "s--")):
            r = [x for x in rows if x.get("kind") == kind and "peak_rss_bytes" in x]
            if not r:
                continue
            f = [x["fibers"] for x in r]
            axes[0].plot(f, [x["peak_rss_bytes"] / 2**30 for x in r], style, label=kind)
            axes[1].plot(f, [x["render_s"] for x in r], style, label=kind)
        for ax, what in zip(axes, ("peak memory of the process (GiB)", "Cycles render (s)")):
            ax.set_xscale("log")
            ax.set_xlabel("fibers")
            ax.set_ylabel(what)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        fig.suptitle(f"Cycles CPU, {Path(a.target).name}, {a.size}, {a.samples} samples: "
                     "explicit curves vs virtual fibers")
        fig.tight_layout()
        fig.savefig(a.plot, dpi=110)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m app.export.figures", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("agreement")
    g.add_argument("--size", default="192x108")
    g.add_argument("--out", default=None, help="folder for the contact sheets")
    g.add_argument("--only", nargs="*")
    g.set_defaults(func=cmd_agreement)
    h = sub.add_parser("harolongo")
    h.add_argument("--size", default="192x108")
    h.add_argument("--samples", type=int, default=4)
    h.set_defaults(func=cmd_harolongo)
    r = sub.add_parser("table2")
    r.add_argument("--target", default=str(HAIR / "sintel_hair.tfx"))
    r.add_argument("--fibers", type=lambda s: int(float(s)), nargs="+", default=[10**4, 10**5, 10**6])
    r.add_argument("--budget", type=float, default=8 * 2**30, help="bytes an explicit row may need (estimate)")
    r.add_argument("--size", default="192x108")
    r.add_argument("--samples", type=int, default=4)
    r.add_argument("--timeout", type=float, default=1800)
    r.add_argument("--plot", default=None)
    r.set_defaults(func=cmd_table2)
    w = sub.add_parser("table2-row")
    w.add_argument("--kind", choices=("virtual", "explicit"), required=True)
    w.add_argument("--fibers", type=lambda s: int(float(s)), required=True)
    w.add_argument("--target", required=True)
    w.add_argument("--size", default="192x108")
    w.add_argument("--samples", type=int, default=4)
    w.add_argument("--work", required=True)
    w.set_defaults(func=cmd_table2_row)
    a = ap.parse_args(argv)
    return a.func(a)


if __name__ == "__main__":
    sys.exit(main())
