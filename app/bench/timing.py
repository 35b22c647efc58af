"""Timing, memory and machine facts for the benchmarks.

llvmpipe renders on the CPU, shares it with everything else on the machine, and moderngl's GL timer query
is 32-bit (it wraps past ~4.3 s), so frames are timed with the wall clock around a render followed by
``ctx.finish()`` (which waits for the GPU, here llvmpipe's threads): warm-up frames first (shader
compilation, first-touch allocation), then the median of at least ``reps`` frames and their coefficient of
variation. The suites render with ``outputs=("draw",)``: nothing is read back, so a frame's time is the
method's rendering, not a read-back or numpy post-processing that both methods would share.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]

# The traversal benches (grooms, quality, the suites, looks) time and count the unfiltered exact traversal: their
# figures in docs/ were taken before quality.filter = coverage became the default (#16), so they pin it off to stay
# comparable; the filter has its own bench (antialias.py), which sets it per mode.
UNFILTERED = {"quality.filter": "off"}


def unfiltered(p):
    """``p`` with the thin-fiber filter off (UNFILTERED)."""
    return p.replace(**UNFILTERED)


@dataclass
class Timing:
    samples_ms: list[float] = field(default_factory=list)

    @property
    def median_ms(self) -> float:
        return float(statistics.median(self.samples_ms)) if self.samples_ms else math.nan

    @property
    def cv(self) -> float:
        """Coefficient of variation: sample standard deviation over mean (0 for fewer than 2 samples)."""
        if len(self.samples_ms) < 2:
            return 0.0
        mean = statistics.fmean(self.samples_ms)
        return float(statistics.stdev(self.samples_ms) / mean) if mean > 0 else 0.0

    @property
    def reps(self) -> int:
        return len(self.samples_ms)


def time_frames(frame: Callable[[], object], *, warmup: int = 2, reps: int = 10,
                sync: Callable[[], object] | None = None) -> Timing:
    """Wall-clock milliseconds of ``frame()`` (plus ``sync()``, e.g. ``ctx.finish``), after ``warmup``
    untimed calls; ``reps`` timed calls."""
    for _ in range(warmup):
        frame()
        if sync:
            sync()
    out = Timing()
    for _ in range(reps):
        t0 = time.perf_counter()
        frame()
        if sync:
            sync()
        out.samples_ms.append((time.perf_counter() - t0) * 1e3)
    return out


def peak_rss_bytes() -> int:
    """This process's peak resident set size (Linux reports ru_maxrss in KiB, macOS in bytes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak if sys.platform == "darwin" else peak * 1024)


def current_rss_bytes() -> int:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return peak_rss_bytes()


def fit_power_law(x, y) -> tuple[float, float, float]:
    """Least-squares fit of log y = log a + b log x: returns (exponent b, prefactor a, R^2)."""
    lx, ly = np.log(np.asarray(x, np.float64)), np.log(np.asarray(y, np.float64))
    ok = np.isfinite(lx) & np.isfinite(ly)
    lx, ly = lx[ok], ly[ok]
    if len(lx) < 2 or np.ptp(lx) == 0:
        return math.nan, math.nan, math.nan
    b, log_a = np.polyfit(lx, ly, 1)
    pred = log_a + b * lx
    ss_res = float(np.sum((ly - pred) ** 2))
    ss_tot = float(np.sum((ly - ly.mean()) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 1.0
    return float(b), float(math.exp(log_a)), r2


def crossover(x, y_a, y_b) -> float | None:
    """First x (log-interpolated) where y_a - y_b changes sign, ``None`` if it never does."""
    x = np.asarray(x, np.float64)
    diff = np.log(np.asarray(y_a, np.float64)) - np.log(np.asarray(y_b, np.float64))
    ok = np.isfinite(diff)
    x, diff = x[ok], diff[ok]
    for i in range(len(x) - 1):
        if diff[i] == 0:
            return float(x[i])
        if diff[i] * diff[i + 1] < 0:
            f = diff[i] / (diff[i] - diff[i + 1])
            return float(math.exp(math.log(x[i]) + f * (math.log(x[i + 1]) - math.log(x[i]))))
    return None


# --------------------------------------------------------------------------------------------------
# The machine
# --------------------------------------------------------------------------------------------------
@dataclass
class Machine:
    date: str
    commit: str
    dirty: bool
    host: str
    os: str
    cpu: str
    cores: int
    cores_usable: int
    memory_bytes: int
    python: str
    numpy: str
    moderngl: str
    gl_renderer: str
    gl_version: str
    mesa: str
    lp_num_threads: str
    commit_end: str = ""           # HEAD when the run ended, if others committed during it

    def as_dict(self) -> dict:
        return asdict(self)

    def markdown(self) -> str:
        commit = self.commit[:12] + (" (with uncommitted changes)" if self.dirty else "")
        if self.commit_end and self.commit_end != self.commit:
            commit += f"; HEAD was `{self.commit_end[:12]}` when the run ended"
        return "\n".join([
            f"- date: {self.date}",
            f"- commit: `{commit}`",
            f"- machine: {self.cpu}, {self.cores_usable} of {self.cores} cores usable, "
            f"{self.memory_bytes / 2**30:.1f} GiB memory; {self.os}",
            f"- renderer: {self.gl_renderer}; OpenGL {self.gl_version}"
            + (f"; LP_NUM_THREADS={self.lp_num_threads}" if self.lp_num_threads else ""),
            f"- software: Python {self.python}, numpy {self.numpy}, moderngl {self.moderngl}",
        ])


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def short_commit() -> str:
    """The checkout's abbreviated HEAD, for a report's header ("unknown" outside git)."""
    return _git("rev-parse", "--short", "HEAD") or "unknown"


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory() -> int:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0


def with_gl(m: Machine, gl_renderer: str, gl_version: str) -> Machine:
    """The machine record taken at the start, completed with the GL strings and the final HEAD."""
    from dataclasses import replace

    mesa = gl_version.split("Mesa", 1)[1].strip() if "Mesa" in gl_version else ""
    return replace(m, gl_renderer=gl_renderer, gl_version=gl_version, mesa=mesa,
                   commit_end=_git("rev-parse", "HEAD") or "")


def machine_info(gl_renderer: str = "", gl_version: str = "") -> Machine:
    import moderngl

    mesa = gl_version.split("Mesa", 1)[1].strip() if "Mesa" in gl_version else ""
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 1
    return Machine(
        date=_dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        commit=_git("rev-parse", "HEAD") or "unknown",
        dirty=bool(_git("status", "--porcelain", "--untracked-files=no")),
        host=platform.node(), os=f"{platform.system()} {platform.release()}", cpu=_cpu_model(),
        cores=os.cpu_count() or 1, cores_usable=usable, memory_bytes=_memory(),
        python=platform.python_version(), numpy=np.__version__, moderngl=moderngl.__version__,
        gl_renderer=gl_renderer, gl_version=gl_version, mesa=mesa,
        lp_num_threads=os.environ.get("LP_NUM_THREADS", ""))
