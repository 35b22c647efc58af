"""Open a .blend and render frame 1 in Cycles, as a render farm does, with nothing but bpy.

Run as a script, never imported by the exporter: it imports only ``bpy`` and ``numpy`` (no vfiber), so a
render through it shows that the file needs nothing the writing machine had::

    python app/export/render_blend.py scene.blend out.npy [--samples N] [--ids] [--threads N]

``out.npy``: the float32 RGBA image (top row first, linear, premultiplied; Cycles' 32-bit EXR). ``--ids``
sets the vfiber Script node's *Debug view* so each covered pixel emits (ring, fiber, guide + 1) exactly;
with ``--samples 1`` and a 0.01 px filter that is one ray per pixel centre, as ``vfiber render --output id``.
Prints one JSON line: render seconds, peak resident memory of this process (bytes), the file's external
paths as Blender lists them (none for a self-contained file) and any error lines Cycles printed.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("blend")
    ap.add_argument("out")
    ap.add_argument("--samples", type=int, default=None, help="override the file's sample count")
    ap.add_argument("--ids", action="store_true", help="emit fiber ids (one ray per pixel centre)")
    ap.add_argument("--threads", type=int, default=0)

    ap.add_argument("--direct-only", action="store_true",
                    help="no indirect light (max bounces 0): the preview's lighting, one key light and a fill")
    a = ap.parse_args(argv)

    import bpy
    import numpy as np

    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(a.blend))
    scene = bpy.context.scene
    external = sorted(bpy.utils.blend_paths(absolute=False))
    scripts = [{"material": mat.name, "mode": node.mode, "filepath": node.filepath,
                "text": node.script.name if node.script else None,
                "text_is_internal": bool(node.script) and not node.script.filepath,
                "bytecode": len(node.bytecode)}
               for mat in bpy.data.materials if mat.node_tree
               for node in mat.node_tree.nodes if node.bl_idname == "ShaderNodeScript"]
    if a.samples is not None:
        scene.cycles.samples = a.samples
        scene.cycles.use_adaptive_sampling = False
    if a.ids:
        scene.cycles.samples = 1
        scene.cycles.use_adaptive_sampling = False
        scene.cycles.pixel_filter_type = "BOX"
        scene.cycles.filter_width = 0.01
        for mat in bpy.data.materials:
            for node in (mat.node_tree.nodes if mat.node_tree else []):
                if node.bl_idname == "ShaderNodeScript" and "debug_view" in node.inputs:
                    node.inputs["debug_view"].default_value = 1
    scene.cycles.seed = 0
    if a.direct_only:
        scene.cycles.max_bounces = 0
    if a.threads:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = a.threads
    stats: list[str] = []
    bpy.app.handlers.render_stats.append(lambda text: stats.append(text))
    im = scene.render.image_settings
    im.file_format, im.color_mode, im.color_depth = "OPEN_EXR", "RGBA", "32"
    with tempfile.TemporaryDirectory() as d:
        scene.render.filepath = os.path.join(d, "frame.exr")
        scene.render.use_file_extension = False
        t = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        seconds = time.perf_counter() - t
        img = bpy.data.images.load(scene.render.filepath)
        w, h = scene.render.resolution_x, scene.render.resolution_y
        buf = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(buf)
    np.save(a.out, np.ascontiguousarray(buf.reshape(h, w, 4)[::-1]))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({"seconds": seconds, "peak_rss_bytes": peak, "external_paths": external, "scripts": scripts,
                      "size": [w, h], "cycles_stats": stats[-1] if stats else "", "samples": scene.cycles.samples}))
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    sys.exit(main())
