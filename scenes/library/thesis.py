"""The thesis's remaining test scenes (Oliveros 2018, Improved Sampling for
Temporal Anti-Aliasing, §5.2), rebuilt procedurally.

Solid colours, diffuse only (specular lighting was off in the thesis). The windows are built as
merged 'arrays' meshes: a wall with the opening cut out, a blue frame, and what fills the
opening (closed blinds; or nothing, with a bright backdrop behind an arched frame).
"""
from __future__ import annotations

import numpy as np

from ..description import Camera, DirectionalLight, Material, MeshSpec, Motion, Scene, SceneObject, Transform
from ..meshes import cylinder
from . import geometry as g
from .common import BLUE, QUICK, SKY, SUN, WALL, _shifted

BACKDROP = (0.85, 0.9, 0.95)      # bright "outside" seen through a window opening
SLAT = (0.82, 0.8, 0.74)
WINDOW_LIGHT = DirectionalLight(direction=(-0.35, -0.55, -1.0), intensity=(1.6, 1.55, 1.45))
WINDOW_AMBIENT = (0.22, 0.22, 0.24)
BLINDS_LIGHT = DirectionalLight(direction=(-0.25, -1.0, -0.45), intensity=(1.7, 1.65, 1.55))


# -- windows ------------------------------------------------------------------------------------
def _slat_section(chord: float, sag: float, tilt_deg: float, y: float, segments: int = 6
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Cross-section of one curved slat (a shallow arc) in the y-z plane: points and smooth normals."""
    u = np.linspace(-1, 1, segments + 1)
    t = np.radians(tilt_deg)
    d = np.array([-np.sin(t), np.cos(t)])           # chord direction (y, z): down and towards +z
    n = np.array([np.cos(t), np.sin(t)])            # bulge direction: up and towards the viewer
    pts = (u[:, None] * chord / 2) * d + (sag * (1 - u ** 2))[:, None] * n + [y, 0.0]
    nrm = (chord / 2) * n[None, :] + (2 * sag * u)[:, None] * d[None, :]    # perpendicular to dP/du
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return pts, nrm


def blinds_slats(width: float, height: float, n_slats: int, tilt_deg: float = 72.0,
                 gap: float = 0.0) -> tuple[g.MeshData, g.MeshData]:
    """Closed venetian blinds filling [-w/2, w/2] x [-h/2 + gap, h/2]: curved, smooth-shaded slats,
    each overlapping the next. Returned as (even slats, odd slats) so that every overlap edge is
    an object boundary."""
    spacing = (height - gap) / n_slats
    chord = spacing / np.sin(np.radians(tilt_deg)) * 1.12      # > spacing: the slats overlap
    sag = 0.1 * chord
    parts: list[list[g.MeshData]] = [[], []]
    for k in range(n_slats):
        pts, nrm = _slat_section(chord, sag, tilt_deg, height / 2 - (k + 0.5) * spacing)
        n3 = np.c_[np.zeros(len(nrm)), nrm]
        parts[k % 2].append(g.strip(np.c_[np.full(len(pts), -width / 2), pts],
                                    np.c_[np.full(len(pts), width / 2), pts], n3, n3))
    return g.merge(*parts[0]), g.merge(*parts[1])


def blinds_window(offset=(0.0, 0.0, 0.0), prefix: str = "", wall=(6.0, 4.0), n_slats: int = 36
                  ) -> list[SceneObject]:
    """A blue-framed window (opening 1.4 x 1.6, centred on `offset`) with closed blinds."""
    ow, oh, fw, depth = 1.4, 1.6, 0.09, 0.12
    hx, hy = ow / 2, oh / 2
    frame = g.merge(
        g.box((ow + 2 * fw, fw, depth), (0, hy + fw / 2, 0)), g.box((ow + 2 * fw, fw, depth), (0, -hy - fw / 2, 0)),
        g.box((fw, oh, depth), (-hx - fw / 2, 0, 0)), g.box((fw, oh, depth), (hx + fw / 2, 0, 0)),
        g.box((ow + 2 * fw + 0.12, 0.05, depth + 0.12), (0, -hy - fw - 0.025, 0.06)))   # sill
    cords = g.merge(*(g.box((0.006, oh - 0.02, 0.006), (x, 0.0, 0.035)) for x in (-0.42, 0.42)))
    even, odd = blinds_slats(ow - 0.02, oh, n_slats, gap=0.07)          # blind not quite lowered
    wall_m = g.wall_with_hole(-wall[0] / 2, wall[0] / 2, -wall[1] / 2, wall[1] / 2,
                              -hx - fw, hx + fw, -hy - fw, hy + fw, z=-depth / 2)
    slat_mat = Material(albedo=SLAT)
    objs = [
        SceneObject(name="wall", mesh=g.spec(wall_m), material=Material(albedo=WALL)),
        *g.surface_objects("frame", frame, Material(albedo=BLUE)),
        SceneObject(name="slats_even", mesh=g.spec(even), material=slat_mat),
        SceneObject(name="slats_odd", mesh=g.spec(odd), material=slat_mat),
        *g.surface_objects("cords", cords, Material(albedo=(0.9, 0.88, 0.82))),
        SceneObject(name="backdrop", mesh=g.spec(g.rect(-hx - 0.3, hx + 0.3, -hy - 0.3, hy + 0.3, -0.6)),
                    material=Material(albedo=BACKDROP)),
    ]
    return [_shifted(o, offset, prefix) for o in objs]


def blinds() -> Scene:
    return Scene(
        name="blinds", resolution=QUICK, transport="direct_shadows",
        description="Close-up of a blue-framed window with closed thin venetian blinds (36 curved slats, "
                    "each shadowing the next), lit from above",
        stresses="dozens of long, nearly horizontal overlap edges a few pixels apart, thin vertical "
                 "cords, and a bright sliver under the blind",
        camera=Camera(position=(0.5, 0.3, 2.4), target=(0.0, -0.02, 0.0), yfov_deg=45, near=0.1, far=20),
        objects=tuple(blinds_window()), lights=(BLINDS_LIGHT,), ambient=WINDOW_AMBIENT, background=SKY)


ARCH_SEGMENTS = 128


def arched_window(offset=(0.0, 0.0, 0.0), prefix: str = "", wall=(4.6, 3.4),
                  segments: int = ARCH_SEGMENTS) -> list[SceneObject]:
    """A blue window frame with a semicircular arch on top (opening 1.2 wide), glazing bars and
    radial muntins, set in a wall; a bright backdrop behind. The arch is tessellated finely
    (`segments` over the half circle) so it reads as a curve, not a polygon, at 1600x900."""
    r, yb, ys = 0.6, -0.9, 0.25        # arch radius, sill height, springing line (arch centre)
    fw, d = 0.07, 0.06                 # frame member width, half depth
    bar = 0.025                        # glazing bar width
    n_half = segments
    frame = g.merge(
        g.arc_member(0, ys, r - fw, r, 0, 180, n_half, -d, d),                      # outer arch
        g.box((fw, ys - yb, 2 * d), (-r + fw / 2, (ys + yb) / 2, 0)),              # jambs
        g.box((fw, ys - yb, 2 * d), (r - fw / 2, (ys + yb) / 2, 0)),
        g.box((2 * r, fw, 2 * d), (0, yb + fw / 2, 0)),                            # bottom rail
        g.box((2 * r + 0.16, 0.05, 2 * d + 0.12), (0, yb - 0.025, 0.06)),           # sill
        g.box((2 * r - 2 * fw, fw * 0.8, 2 * d), (0, ys, 0)),                      # transom
        g.box((bar, ys - yb - fw, 1.6 * d), (0, (ys + yb + fw) / 2, 0)),           # mullion
        g.box((2 * r - 2 * fw, bar, 1.6 * d), (0, (ys + yb) / 2 + 0.1, 0)),        # glazing bar
        g.arc_member(0, ys, 0.26, 0.26 + bar, 0, 180, n_half // 2, -0.8 * d, 0.8 * d),   # inner arch
    )
    rr0, rr1 = 0.26 + bar, r - fw                  # radial muntins between the two arches
    mid = (rr0 + rr1) / 2
    muntins = [g.box((rr1 - rr0 + 0.01, bar, 1.6 * d),
                     (mid * np.cos(np.radians(a)), ys + mid * np.sin(np.radians(a)), 0), (0, 0, 1), a)
               for a in (30.0, 60.0, 90.0, 120.0, 150.0)]
    frame = g.merge(frame, *muntins)
    w0, w1 = wall
    wall_m = g.merge(
        g.rect(-w0 / 2, -r, -w1 / 2, w1 / 2), g.rect(r, w0 / 2, -w1 / 2, w1 / 2),
        g.rect(-r, r, -w1 / 2, yb), g.spandrel(0, ys, r, w1 / 2, n_half))
    objs = [
        SceneObject(name="wall", mesh=g.spec(wall_m), material=Material(albedo=WALL)),
        *g.surface_objects("frame", frame, Material(albedo=BLUE)),
        SceneObject(name="backdrop", mesh=g.spec(g.rect(-r - 0.4, r + 0.4, yb - 0.3, ys + r + 0.4, -0.7)),
                    material=Material(albedo=BACKDROP)),
    ]
    return [_shifted(o, offset, prefix) for o in objs]


def arched() -> Scene:
    return Scene(
        name="arched_window", resolution=QUICK, transport="direct",
        description="Close-up of a blue window with a semicircular arch, radial muntins and glazing bars, "
                    "against a bright backdrop",
        stresses="curved edges at every orientation (finely tessellated arch), thin bars against a "
                 "bright background",
        camera=Camera(position=(0.4, 0.12, 2.45), target=(0.0, -0.02, 0.0), yfov_deg=45, near=0.1, far=20),
        objects=tuple(arched_window()), lights=(WINDOW_LIGHT,), ambient=WINDOW_AMBIENT, background=SKY)


def hard_edges() -> Scene:
    """The windows, the pipe and the text wall side by side, seen from far away."""
    from ..builtin import pipe, text_wall
    ground = g.moved(g.rect(-9.0, 9.0, -14.0, 3.0), (0.0, -1.5, 0.0), (1, 0, 0), -90.0)
    objs = [SceneObject(name="ground", mesh=g.spec(ground), material=Material(albedo=(0.45, 0.43, 0.4)))]
    objs += blinds_window((-5.6, 0.0, 0.0), "blinds_", wall=(2.4, 2.4), n_slats=36)
    objs += arched_window((-2.6, 0.0, 0.0), "arched_", wall=(2.2, 2.4))
    p = pipe().objects[0]
    objs.append(_shifted(p, (0.8, 0.1, 0.3)))
    objs.append(SceneObject(name="pipe_wall", mesh=g.spec(g.rect(-0.8, 2.4, -1.2, 1.2, -0.2)),
                            material=Material(albedo=WALL)))
    t = text_wall().objects[0]
    objs.append(_shifted(t, (4.7, 0.2, 0.0)))
    return Scene(
        name="hard_edges", resolution=QUICK, transport="direct",
        description="The blinds window, the arched window, the pipe and the text wall side by side, "
                    "seen from far away",
        stresses="geometric and texture detail at or below pixel size: slats, bars and letters that "
                 "alias into crawling patterns",
        camera=Camera(position=(0.6, 1.2, 16.0), target=(-0.3, 0.0, 0.0), yfov_deg=30, near=0.5, far=60),
        objects=tuple(objs), lights=(SUN, WINDOW_LIGHT), ambient=(0.18, 0.18, 0.2), background=SKY)


# -- hairball ------------------------------------------------------------------------------------
HAIRBALL_FIBRES = 560
HAIRBALL_SEGMENTS = 16
HAIRBALL_MAX_TRIANGLES = 60000


def hairball_paths(n: int = HAIRBALL_FIBRES, segments: int = HAIRBALL_SEGMENTS, radius: float = 1.0,
                   seed: int = 11) -> np.ndarray:
    """Curly fibres confined to a ball: each is a random walk whose direction turns about a slowly
    drifting axis (a curl), pulled back when it leaves the ball. (n, segments + 1, 3)."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    p *= (radius * rng.random((n, 1)) ** (1 / 3) * 0.9) / np.linalg.norm(p, axis=1, keepdims=True)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    curl = rng.normal(size=(n, 3)) * 0.45
    step = 2.2 * radius / segments
    out = [p.copy()]
    for _ in range(segments):
        curl += rng.normal(size=(n, 3)) * 0.15
        d = d + np.cross(curl, d)
        r = np.linalg.norm(p, axis=1, keepdims=True)
        outward = np.sum(d * p, axis=1, keepdims=True) / np.maximum(r, 1e-9)
        pull = np.clip((r - 0.75 * radius) / (0.25 * radius), 0, 1) * np.maximum(outward, 0)
        d = d - 1.6 * pull * p / np.maximum(r, 1e-9)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        p = p + step * d
        out.append(p.copy())
    return np.stack(out, 1)


HAIR_COLOURS = 16


def _hair_palette(k: int = HAIR_COLOURS) -> np.ndarray:
    """(k, 3) shades of brown-orange, one per fibre group (so unlit fibres stay readable)."""
    t = np.random.default_rng(5).permutation(np.linspace(0, 1, k))
    return np.array([0.55, 0.32, 0.12]) * (0.55 + 0.45 * t[:, None]) + np.array([0.1, 0.08, 0.02]) * t[:, None]


def hairball_objects(spin_deg: float = 0.0) -> tuple[SceneObject, ...]:
    """The fibres as HAIR_COLOURS meshes, one per colour (fibre i has colour i mod k). One mesh
    would do for rendering; groups keep fibre-over-fibre edges mostly object boundaries, which the
    agreement check needs (see geometry.py)."""
    paths = hairball_paths()
    pal = _hair_palette()
    motion = Motion(spin_axis=(0.15, 1.0, 0.1), spin_deg=spin_deg)
    return tuple(SceneObject(name=f"fibres_{c}", mesh=g.spec(g.tubes(paths[c::len(pal)], radius=0.007, sides=3)),
                             material=Material(albedo=tuple(float(x) for x in pal[c])), motion=motion)
                 for c in range(len(pal)))


def hairball(lit: bool, rotating: bool) -> Scene:
    name = "hairball" + ("_rotating" if rotating else "") + ("_lit" if lit else "_unlit")
    frames = 100 if rotating else 1
    what = f"{HAIRBALL_FIBRES} curly fibres (thin triangular tubes, {HAIR_COLOURS} meshes by colour) in a ball"
    return Scene(
        name=name, resolution=QUICK, frames=frames,
        transport="direct_shadows" if lit else "unlit",
        description=what + (", spinning 1.8 degrees a frame for 100 frames" if rotating else "")
        + (", lit by the sun with shadows" if lit else ", unlit (albedo only)"),
        stresses="a dense tangle of sub-pixel to one-pixel fibres: nearly every pixel has edges"
                 + ("; self-shadowing makes the shading as noisy as the geometry" if lit else "")
                 + ("; rotation disocclusions everywhere, motion vectors of thin geometry" if rotating else ""),
        camera=Camera(position=(0.0, 0.35, 3.1), target=(0.0, 0.0, 0.0), yfov_deg=42, near=0.1, far=20),
        objects=hairball_objects(1.8 if rotating else 0.0),
        lights=(DirectionalLight(direction=(-0.5, -0.8, -0.45), intensity=(2.4, 2.3, 2.1)),) if lit else (),
        ambient=(0.12, 0.12, 0.14) if lit else (0.0, 0.0, 0.0), background=(0.22, 0.25, 0.3))


# -- atrium --------------------------------------------------------------------------------------
def _arcade(xs, height: float, col_r: float, depth: float, segments: int) -> g.MeshData:
    """Arches between consecutive column positions `xs` along x (in the plane z = 0): for each bay
    the wall above a semicircular arch, front and back, and the arch's soffit."""
    parts = []
    for x0, x1 in zip(xs[:-1], xs[1:]):
        cx, r = (x0 + x1) / 2, (x1 - x0) / 2 - col_r
        spring = height - r - 0.25
        for z in (-depth / 2, depth / 2):
            parts.append(g.spandrel(cx, spring, r, height, segments, z))
        parts.append(g.soffit(cx, spring, r, segments, -depth / 2, depth / 2))
    return g.merge(*parts)


def atrium() -> Scene:
    """A courtyard after Sponza's atrium: two arcades of round columns carrying semicircular arches
    along its length, a back wall with three arched openings, a floor and a static sphere."""
    zs = [-3.0, -1.8, -0.6, 0.6, 1.8, 3.0]
    col_r, col_h, top, depth, side = 0.13, 1.6, 2.6, 0.3, 1.9
    piers = 0.14                       # half width of the pier above each column
    columns, stone, arches = [], [], []
    for x in (-side, side):
        for z in zs:
            columns.append(g.moved(g.oriented(cylinder(col_r, col_h, 48, True)), (x, col_h / 2, z)))
            stone.append(g.box((0.32, 0.08, 0.32), (x, col_h + 0.04, z)))          # capital
            stone.append(g.box((0.32, 0.1, 0.32), (x, 0.05, z)))                   # base
            stone.append(g.box((depth, top - col_h - 0.08, 2 * piers), (x, (top + col_h + 0.08) / 2, z)))
        arc_m = _arcade(zs, top, piers, depth, 24)
        arches.append(g.moved(arc_m, (x, 0, 0), (0, 1, 0), 90.0))
        arches.append(g.box((depth + 0.1, 0.3, 6.6), (x, top + 0.15, 0.0)))        # entablature
    back = [g.rect(-3.2, -1.95, 0.0, 3.2), g.rect(-1.05, -0.45, 0.0, 3.2), g.rect(0.45, 1.05, 0.0, 3.2),
            g.rect(1.95, 3.2, 0.0, 3.2)]
    back += [g.spandrel(cx, 1.5, 0.45, 3.2, 24) for cx in (-1.5, 0.0, 1.5)]
    back_m = g.merge(*back)
    objs = [
        SceneObject(name="floor", mesh=g.spec(g.moved(g.rect(-4, 4, -4.5, 4.5), axis=(1, 0, 0), deg=-90)),
                    material=Material(albedo=(0.55, 0.5, 0.45))),
        SceneObject(name="columns", mesh=g.spec(g.merge(*columns)), material=Material(albedo=WALL)),
        *g.surface_objects("stone", g.merge(*stone), Material(albedo=(0.75, 0.72, 0.66))),
        *g.surface_objects("arches", g.merge(*arches), Material(albedo=(0.78, 0.7, 0.58))),
        SceneObject(name="back_wall", mesh=g.spec(g.moved(back_m, (0, 0, -3.6))),
                    material=Material(albedo=(0.62, 0.6, 0.56))),
        SceneObject(name="sphere", mesh=MeshSpec(kind="sphere", radius=0.45, segments=48, smooth=True),
                    material=Material(albedo=(0.7, 0.15, 0.1)), transform=Transform(translate=(0, 0.45, 0))),
    ]
    return Scene(
        name="atrium", resolution=QUICK, transport="direct_shadows",
        description="A courtyard after Sponza's atrium: arcades of round columns and semicircular arches, "
                    "an arched back wall and a static sphere, lit by the sun with shadows",
        stresses="shadow edges, thin column silhouettes and curved arch edges at several depths",
        camera=Camera(position=(0.35, 1.45, 5.6), target=(0.0, 1.1, -1.0), yfov_deg=55, far=40),
        objects=tuple(objs), lights=(DirectionalLight(direction=(-0.55, -1.0, -0.35), intensity=(2.2, 2.1, 1.9)),),
        ambient=(0.2, 0.21, 0.24), background=SKY)
