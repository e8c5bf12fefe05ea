"""The glTF 2.0 metallic-roughness BRDF (the glTF 2.0 specification, appendix B), in Dr.Jit.

    c_diff = lerp(baseColor, 0, metallic)        F0 = lerp(0.04, baseColor, metallic)
    alpha  = roughness^2
    F      = F0 + (1 - F0) (1 - |V.H|)^5                                   (Schlick 1994)
    D      = alpha^2 chi+(N.H) / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2)        (Trowbridge-Reitz / GGX,
                                                                            Walter et al. 2007)
    G      = G1(L) G1(V),  G1(X) = 2 |N.X| / (|N.X| + sqrt(alpha^2 + (1 - alpha^2) (N.X)^2))
    f      = (1 - F) c_diff / pi + F D G / (4 |N.L| |N.V|)

G is the specification's separable Smith form (not the height-correlated one of the Khronos
sample viewer); with it G / (4 |N.L| |N.V|) = 1 / ((|N.L| + sqrt(..L..)) (|N.V| + sqrt(..V..))),
which has no division by a grazing cosine. (N.H)^2 (alpha^2 - 1) + 1 is evaluated as
|N x H|^2 + (N.H)^2 alpha^2, its exact equal for unit vectors, which keeps float32's relative
precision where alpha is small and N.H near 1. alpha is clamped at MIN_ALPHA: at roughness 0 the
distribution is a delta that no sample of a point or directional light can find (and D is 0/0).
"""
from __future__ import annotations

import math

from backend import dr, mi

MIN_ALPHA = 1e-3       # roughness ~0.032: the sharpest highlight the model renders
DIELECTRIC_F0 = 0.04   # the specification's ior 1.5


def lobes(roughness, metallic, base: mi.Color3f):
    """(c_diff, F0, alpha) of a base colour, metallic and perceptual roughness."""
    c_diff = base * (1.0 - metallic)
    f0 = dr.lerp(mi.Color3f(DIELECTRIC_F0), base, metallic)
    alpha = dr.maximum(dr.square(roughness), MIN_ALPHA)
    return c_diff, f0, alpha


def gltf_brdf(n: mi.Vector3f, v: mi.Vector3f, l: mi.Vector3f, base: mi.Color3f, metallic, roughness) -> mi.Color3f:
    """f(v, l) in 1/sr for unit normal n, unit directions v (to the viewer) and l (to the light).
    Zero where l is below the surface; |N.V| as the specification writes it where v is not."""
    c_diff, f0, alpha = lobes(roughness, metallic, base)
    nl = dr.dot(n, l)
    nv = dr.maximum(dr.abs(dr.dot(n, v)), 1e-6)
    h = dr.normalize(l + v)
    nh = dr.dot(n, h)
    vh = dr.abs(dr.dot(v, h))
    a2 = dr.square(alpha)
    f = f0 + (1.0 - f0) * dr.power(dr.maximum(1.0 - vh, 0.0), 5)
    nxh = dr.cross(n, h)
    d = a2 / (math.pi * dr.square(dr.dot(nxh, nxh) + dr.square(nh) * a2))
    d = dr.select(nh > 0, d, 0.0)
    vis = dr.rcp((nl + dr.sqrt(a2 + (1.0 - a2) * dr.square(nl))) * (nv + dr.sqrt(a2 + (1.0 - a2) * dr.square(nv))))
    out = (1.0 - f) * c_diff * (1.0 / math.pi) + f * (d * vis)
    return dr.select(nl > 0, out, 0.0)


def ambient_response(nv, base: mi.Color3f, metallic, roughness) -> mi.Color3f:
    """Reflectance of the model under a constant environment (the scene's ambient term): the
    specular part by Karis's analytic fit of the split-sum environment BRDF ("Physically Based
    Shading on Mobile", Karis 2014), E = F0 A + B, and the diffuse part c_diff weighted by 1 - E."""
    c_diff, f0, _ = lobes(roughness, metallic, base)
    r0 = roughness * -1.0 + 1.0
    r1 = roughness * -0.0275 + 0.0425
    r2 = roughness * -0.572 + 1.04
    r3 = roughness * 0.022 - 0.04
    a004 = dr.minimum(r0 * r0, dr.exp(-9.28 * math.log(2.0) * dr.abs(nv))) * r0 + r1
    e = f0 * (-1.04 * a004 + r2) + (1.04 * a004 + r3)
    e = dr.clip(e, 0.0, 1.0)
    return c_diff * (1.0 - e) + e
