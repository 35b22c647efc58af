"""When the viewer process started: taken before the heavy imports (imgui, moderngl, the renderer), so the
console's "window up / first picture after n s" lines count from the moment ``vfiber view`` began."""

from __future__ import annotations

import time

T_START = time.perf_counter()
