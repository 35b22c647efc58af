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
    from app.export.blend import BlendStats  # noqa: F401  (the exporter must import without bpy)

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
        print(f"| {r['name']} | {r['segments']} | {r['coverage']:.2%} | {r['same_id']:.2%} | {r['colour_diff']:.1f} | "
              f"{bias} | {r['export_s']:.1f} s | {r['ids_s']:.1f} s / {r['shaded_s']:.1f} s | {r['peak_mib']:.0f} MiB |")
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
    a = ap.parse_args(argv)
    return a.func(a)


if __name__ == "__main__":
    sys.exit(main())
