"""The built-in scene library beyond the first few scenes of scenes/builtin.py, all procedural.

thesis.py      the thesis's remaining test scenes (Oliveros 2018, §5.2): blinds, arched window, hard
               edges seen from far, the hairball (static / rotating, unlit / lit), the atrium
hard_cases.py  cases chosen to break TAA: sub-pixel lines, moire, HDR contrast, a fast object,
               disocclusion, a camera cut
modern.py      today's hard cases: specular shimmer on normal-mapped metal, highlights on thin
               rails, swaying alpha-tested foliage, and a scene combining them
common.py      palette, lights and small helpers shared with scenes/builtin.py
geometry.py    mesh builders (merged 'arrays' meshes: arches, strips, tubes)
"""
