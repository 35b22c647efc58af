"""Limits of the fiber model that the shaders are compiled with (injected as defines: ``defines.py``).

Changing one here changes the GLSL (``model_defines`` in app/render/renderer.py, the explicit baseline's
program) and the OSL export (``osl_defines``) together; nothing else spells these numbers.
"""

from __future__ import annotations

#: rings per container: the length of the per-ring uniform arrays (glsl/fibers/layout.glsl: uRingA...)
#: and the OSL export's bound on fibers.rings (osl/stages/container.osl)
MAX_RINGS = 64
#: chord pieces per arc of a curved-fiber ring (glsl/fibers/curved.glsl: chord_pieces)
MAX_SUB = 16
