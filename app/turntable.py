"""Turntables: the camera orbits the hair, one PNG per pose, and a video where ffmpeg is installed.

``vfiber turntable TARGET -o DIR`` and the viewer's File > Render turntable both come here. Frame n looks
from ``camera.azimuth + n * degrees / frames`` (``--light``: the camera stays and the lights turn,
``light.rig_rotation``); everything else (framing, look, quality) is the preset's.
Frames are written through temporary files, so an interrupted turntable never leaves half a PNG.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from .params import Params

FRAME_PATTERN = "frame_{:04d}.png"
VIDEO_NAME = "turntable.mp4"
FPS = 24


@dataclass
class Turntable:
    frames: list[Path] = field(default_factory=list)
    video: Path | None = None
    video_note: str = ""          # why there is no video


def render_turntable(p: Params, out_dir: str | Path, *, frames: int = 36, size=(640, 360), alpha: bool = False,
                     degrees: float = 360.0, video: bool = True, light: bool = False, renderer=None, scene=None,
                     progress: Callable[[int, int, Path], None] | None = None) -> Turntable:
    """Render the turntable into ``out_dir``. ``light``: turn the lights (light.rig_rotation) instead of
    the camera. ``renderer``/``scene``: reuse the caller's (the viewer's GL context); otherwise a headless
    context is made for the duration."""
    result = Turntable()
    if renderer is not None:
        for n, path in iter_turntable(p, out_dir, renderer, scene, frames=frames, size=size, alpha=alpha,
                                      degrees=degrees, light=light):
            result.frames.append(path)
            if progress is not None:
                progress(n, frames, path)
    else:
        from .gl.context import create_headless
        from .render.renderer import Renderer
        from .scene.generators import build_scene

        scene = build_scene(p)
        with create_headless() as gl:
            r = Renderer(gl.ctx)
            r.set_scene(scene)
            return render_turntable(p, out_dir, frames=frames, size=size, alpha=alpha, degrees=degrees,
                                    video=video, light=light, renderer=r, scene=scene, progress=progress)
    if video:
        result.video, result.video_note = encode_video(Path(out_dir), frames)
    else:
        result.video_note = "not asked for"
    return result


def iter_turntable(p: Params, out_dir: str | Path, renderer, scene, *, frames: int = 36, size=(640, 360),
                   alpha: bool = False, degrees: float = 360.0, light: bool = False) -> Iterator[tuple[int, Path]]:
    """One frame per step, (frames done, path written): the viewer renders one per displayed frame, so
    it stays responsive and shows how far it is."""
    from PIL import Image

    from .atomic import atomic_path
    from .output import unpremultiplied_rgba
    from .render.camera import Camera

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    key = "light.rig_rotation" if light else "camera.azimuth"
    start = p[key]
    for n in range(frames):
        angle = (start + n * degrees / frames + 180.0) % 360.0 - 180.0
        q = p.replace(**{key: angle})
        cam = Camera.from_params(q, scene, size[0] / size[1])
        frame = renderer.render_quality(q, cam, tuple(size), outputs=("color",))
        img = unpremultiplied_rgba(frame, q) if alpha else frame.color
        path = out / FRAME_PATTERN.format(n)
        with atomic_path(path) as tmp:
            Image.fromarray(img).save(tmp, format="PNG")
        yield n + 1, path


def encode_video(folder: Path, frames: int) -> tuple[Path | None, str]:
    """frame_%04d.png -> turntable.mp4 (H.264, yuv420p so every player opens it); (None, why) otherwise."""
    ffmpeg = shutil.which("ffmpeg")
    if ffmpeg is None:
        return None, "ffmpeg is not installed (apt install ffmpeg); the PNG frames are complete"
    target = folder / VIDEO_NAME
    cmd = [ffmpeg, "-y", "-loglevel", "error", "-framerate", str(FPS), "-i", str(folder / "frame_%04d.png"),
           "-frames:v", str(frames), "-c:v", "libx264", "-pix_fmt", "yuv420p",
           "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", str(target)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or not target.exists():
        last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
        return None, f"ffmpeg failed ({last}); the PNG frames are complete"
    return target, ""
