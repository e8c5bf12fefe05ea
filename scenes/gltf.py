"""Whole glTF 2.0 scenes (.gltf / .glb), expanded at load time into ordinary scene objects.

An object with `mesh = { kind = "gltf", path = "...", camera = true }` becomes one scene object per
mesh primitive of the file's default scene, each with its node's world matrix baked into its
vertices and its own material: the metallic-roughness model (shading/brdf.py) with baseColorFactor,
the sRGB baseColorTexture, metallicFactor, roughnessFactor, metallicRoughnessTexture (G roughness,
B metallic), normalTexture (+ scale; on the primitive's TANGENTs where it has them, else tangents
generated per triangle from the UVs), emissiveFactor (x KHR_materials_emissive_strength) and emissiveTexture, occlusionTexture
(+ strength; scales the ambient term), all sampled on the first texture's TEXCOORD_n, and alphaMode
MASK / alphaCutoff as the cut-out. The object's own transform and motion
apply on top, to the whole file. With `camera = true` the first perspective camera placed in the
scene supplies the view, field by field where the scene file's [camera] does not set it.

The container is read here rather than through trimesh's glTF importer, which reads TEXCOORD_0 for
every texture, ignores accessors' `normalized` flag and sparse storage, and places a camera by its
own node's matrix only. Everything the shading cannot represent is collected and reported once.
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from .description import Material, MeshSpec, SceneObject, Texture
from .gltf_container import _LINEAR, _MODES, _WRAP, SUPPORTED_EXTENSIONS, _Container, _Malformed
from .meshes import MeshData, SceneError, SceneWarning, degenerate_faces


@dataclass
class Expanded:
    objects: list[SceneObject]
    meshes: list[MeshData]
    camera: dict | None                 # Camera fields in the glTF's world (before the object transform)
    digests: list[str] = field(default_factory=list)   # sha256 of the file and every file it names



def _node_matrix(node: dict, where: str) -> np.ndarray:
    if "matrix" in node:
        m = np.asarray(node["matrix"], float)
        if m.shape != (16,):
            raise _Malformed(f"{where}.matrix", f"needs 16 numbers, got {m.size}")
        m = m.reshape(4, 4).T                      # stored column-major
    else:
        from scipy.spatial.transform import Rotation
        m = np.eye(4)
        q = np.asarray(node.get("rotation", (0.0, 0.0, 0.0, 1.0)), float)   # x, y, z, w
        if q.shape != (4,) or not np.all(np.isfinite(q)) or not np.linalg.norm(q):
            raise _Malformed(f"{where}.rotation", f"not a quaternion: {node.get('rotation')}")
        m[:3, :3] = Rotation.from_quat(q).as_matrix() * np.asarray(node.get("scale", (1.0, 1.0, 1.0)), float)
        m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    if not np.all(np.isfinite(m)):
        raise _Malformed(where, "transform is not finite")
    return m


def _walk(c: _Container) -> list[tuple[int, np.ndarray]]:
    """(node index, world matrix) for every node of the default scene, depth first."""
    nodes = c.json.get("nodes", [])
    if c.json.get("scenes"):
        s = c.json.get("scene", 0)
        roots = c.item("scenes", s, "scene").get("nodes", [])
    else:   # no scene: every node that is nobody's child
        children = {k for n in nodes for k in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out, seen = [], set()
    stack = [(r, np.eye(4), "scenes.nodes") for r in reversed(roots)]
    while stack:
        i, parent, via = stack.pop()
        node = c.item("nodes", i, via)
        if i in seen:
            raise _Malformed(f"nodes[{i}]", "reached twice: the node hierarchy is not a tree")
        seen.add(i)
        world = parent @ _node_matrix(node, f"nodes[{i}]")
        out.append((i, world))
        stack += [(k, world, f"nodes[{i}].children") for k in reversed(node.get("children", []))]
    return out


def _faces(c: _Container, p: dict, n_vertices: int, where: str) -> np.ndarray | None:
    mode = p.get("mode", 4)
    if "indices" in p:
        idx = c.accessor(p["indices"], f"{where}.indices", (1,))[:, 0].astype(np.int64)
    else:
        idx = np.arange(n_vertices, dtype=np.int64)
    if mode == 4:
        return idx[:len(idx) - len(idx) % 3].reshape(-1, 3)
    k = np.arange(max(len(idx) - 2, 0))
    if mode == 5:   # strip: odd triangles swap their first two vertices to keep the winding
        return np.stack([idx[k + (k % 2)], idx[k + 1 - (k % 2)], idx[k + 2]], 1)
    if mode == 6:   # fan around the first vertex
        return np.stack([idx[k + 1], idx[k + 2], np.full_like(k, idx[0])], 1)
    return None


class _Materials:
    """Scene materials per glTF material index, with decoded textures shared between users."""

    def __init__(self, c: _Container, unsupported: set[str]):
        self.c, self.unsupported = c, unsupported
        self._rgb: dict[int, np.ndarray] = {}
        self._alpha: dict[int, np.ndarray] = {}
        self._data: dict[int, np.ndarray] = {}
        self._made: dict = {}

    def _image(self, tex_index: int, where: str) -> int:
        import colour
        t = self.c.item("textures", tex_index, where)
        src = t.get("source", t.get("extensions", {}).get("EXT_texture_webp", {}).get("source"))
        if src is None:
            raise _Malformed(f"textures[{tex_index}]", "has no image source this loader can read "
                             f"(extensions: {sorted(t.get('extensions', {}))})")
        if "sampler" in t:
            s = self.c.item("samplers", t["sampler"], f"textures[{tex_index}].sampler")
            for key in ("wrapS", "wrapT"):
                if s.get(key) in _WRAP:
                    self.unsupported.add(f"sampler {key} {_WRAP[s[key]]} (textures repeat)")
            if {s.get("magFilter"), s.get("minFilter")} & _LINEAR:
                self.unsupported.add("linear/mipmap texture filtering (textures are sampled nearest-texel)")
        if src not in self._rgb:
            rgba = self.c.image_rgba(src, f"textures[{tex_index}].source")[::-1]   # row 0 = v 0
            lin = colour.cctf_decoding(rgba[..., :3].astype(np.float32) / 255.0, function="sRGB")
            self._rgb[src] = np.ascontiguousarray(lin, np.float32)
            self._alpha[src] = np.ascontiguousarray(rgba[..., 3], np.float32) / np.float32(255.0)
            # data textures (normal, metallic-roughness, occlusion) are stored linearly
            self._data[src] = np.ascontiguousarray(rgba[..., :3], np.float32) / np.float32(255.0)
        return src

    def _maps(self, m: dict, pbr: dict, where: str) -> tuple[dict, int | None]:
        """The material's textures by Material field, and the texcoord set they are sampled on
        (the first texture's; one set per primitive is kept, a texture on another is reported)."""
        roles = (("texture", pbr.get("baseColorTexture"), "pbrMetallicRoughness.baseColorTexture", "rgb"),
                 ("metallic_roughness", pbr.get("metallicRoughnessTexture"),
                  "pbrMetallicRoughness.metallicRoughnessTexture", "data"),
                 ("normal_map", m.get("normalTexture"), "normalTexture", "data"),
                 ("emission_texture", m.get("emissiveTexture"), "emissiveTexture", "rgb"),
                 ("occlusion", m.get("occlusionTexture"), "occlusionTexture", "data"))
        out, texcoord = {}, None
        for field_name, tinfo, key, kind in roles:
            if tinfo is None:
                continue
            src = self._image(tinfo["index"], f"{where}.{key}.index")
            out[field_name] = Texture(kind="array", data=(self._rgb if kind == "rgb" else self._data)[src])
            k = int(tinfo.get("texCoord", 0))
            if texcoord is None:
                texcoord = k
            elif k != texcoord:
                self.unsupported.add(f"{key.split('.')[-1]} on TEXCOORD_{k} (sampled on TEXCOORD_{texcoord})")
            for ext in tinfo.get("extensions", {}):
                self.unsupported.add(ext)
        return out, texcoord

    @staticmethod
    def _unit(d: dict, key: str, default: float, where: str) -> float:
        v = d.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 1:
            raise _Malformed(f"{where}.{key}", f"must be a number in [0, 1], got {v!r}")
        return float(v)

    def get(self, index: int | None, where: str) -> tuple[Material | None, int | None]:
        """(material, texcoord set) for a glTF material index; material None = cut out entirely."""
        if index in self._made:
            return self._made[index]
        if index is None:
            # the specification's default material: white, fully metallic, fully rough
            made = (Material(albedo=(1.0, 1.0, 1.0), metallic=1.0, roughness=1.0), None)
            self._made[index] = made
            return made
        m = self.c.item("materials", index, where)
        where = f"materials[{index}]"
        pbr = m.get("pbrMetallicRoughness", {})
        factor = np.asarray(pbr.get("baseColorFactor", (1.0, 1.0, 1.0, 1.0)), float)
        if factor.shape != (4,) or not np.all(np.isfinite(factor)) or factor.min() < 0:
            raise _Malformed(f"{where}.pbrMetallicRoughness.baseColorFactor",
                             f"needs 4 finite numbers >= 0, got {pbr.get('baseColorFactor')}")
        emissive = np.asarray(m.get("emissiveFactor", (0.0, 0.0, 0.0)), float) * \
            m.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
        if emissive.shape != (3,) or not np.all(np.isfinite(emissive)) or emissive.min() < 0:
            raise _Malformed(f"{where}.emissiveFactor", f"needs 3 finite numbers >= 0, got {m.get('emissiveFactor')}")
        metallic = self._unit(pbr, "metallicFactor", 1.0, f"{where}.pbrMetallicRoughness")
        roughness = self._unit(pbr, "roughnessFactor", 1.0, f"{where}.pbrMetallicRoughness")
        normal_scale = m.get("normalTexture", {}).get("scale", 1.0)
        if isinstance(normal_scale, bool) or not isinstance(normal_scale, (int, float)) \
                or not np.isfinite(normal_scale):
            raise _Malformed(f"{where}.normalTexture.scale", f"must be a finite number, got {normal_scale!r}")
        strength = self._unit(m.get("occlusionTexture", {}), "strength", 1.0, f"{where}.occlusionTexture")
        for ext in m.get("extensions", {}):
            if ext not in SUPPORTED_EXTENSIONS:
                self.unsupported.add(ext)

        mode = m.get("alphaMode", "OPAQUE")
        if mode not in ("OPAQUE", "MASK", "BLEND"):
            raise _Malformed(f"{where}.alphaMode", f"must be OPAQUE, MASK or BLEND, got {mode!r}")
        cutoff = float(m.get("alphaCutoff", 0.5))
        if mode == "BLEND":
            self.unsupported.add("alphaMode BLEND (cut out as MASK at 0.5)")
            cutoff = 0.5
        if not np.isfinite(cutoff):
            raise _Malformed(f"{where}.alphaCutoff", f"must be finite, got {cutoff}")

        alpha = None
        maps, texcoord = self._maps(m, pbr, where)
        texture = maps.pop("texture", None)
        if texture is not None:
            src = self._image(pbr["baseColorTexture"]["index"], f"{where}.pbrMetallicRoughness.baseColorTexture.index")
        if mode != "OPAQUE" and cutoff > 0:
            if texture is None:
                # A constant alpha keeps all or nothing.
                if factor[3] < cutoff:
                    self.unsupported.add("primitives cut out entirely by their alpha (omitted)")
                    self._made[index] = (None, None)
                    return self._made[index]
            elif cutoff > 1 or factor[3] * self._alpha[src].max() < cutoff:
                self.unsupported.add("primitives cut out entirely by their alpha (omitted)")
                self._made[index] = (None, None)
                return self._made[index]
            elif factor[3] * self._alpha[src].min() < cutoff:
                alpha = Texture(kind="array", data=self._alpha[src] * np.float32(factor[3]))
        mat = Material(albedo=tuple(factor[:3]), emission=tuple(emissive), texture=texture, alpha=alpha,
                       alpha_threshold=min(cutoff, 1.0) if alpha is not None else 0.5,
                       metallic=metallic, roughness=roughness, normal_scale=float(normal_scale),
                       occlusion_strength=strength, **maps)
        self._made[index] = (mat, texcoord)
        return self._made[index]


def _camera(c: _Container, placed: list[tuple[int, np.ndarray]]) -> dict:
    """Camera fields of the lowest-numbered camera that a node of the scene places."""
    nodes = c.json.get("nodes", [])
    users = [(nodes[i]["camera"], i, m) for i, m in placed if "camera" in nodes[i]]
    if not users:
        raise _Malformed("cameras", "camera = true, but no node of the scene places a camera")
    index, node, world = min(users, key=lambda u: u[0])
    cam = c.item("cameras", index, f"nodes[{node}].camera")
    where = f"cameras[{index}]"
    if cam.get("type") != "perspective":
        raise _Malformed(f"{where}.type", f"only perspective cameras are supported, got {cam.get('type')!r}")
    p = cam.get("perspective", {})
    yfov, znear = p.get("yfov"), p.get("znear")
    if not isinstance(yfov, (int, float)) or not 0 < yfov < np.pi:
        raise _Malformed(f"{where}.perspective.yfov", f"must be in (0, pi) radians, got {yfov!r}")
    if not isinstance(znear, (int, float)) or not znear > 0:
        raise _Malformed(f"{where}.perspective.znear", f"must be > 0, got {znear!r}")
    # The camera looks down its node's -z with +y up.
    pos = world[:3, 3]
    fwd, up = world[:3, :3] @ (0.0, 0.0, -1.0), world[:3, :3] @ (0.0, 1.0, 0.0)
    if not np.linalg.norm(fwd) or not np.linalg.norm(up):
        raise _Malformed(f"nodes[{node}]", "the camera node's transform collapses the view direction")
    out = {"position": pos, "target": pos + fwd / np.linalg.norm(fwd), "up": up / np.linalg.norm(up),
           "yfov_deg": float(np.degrees(yfov)), "near": float(znear)}
    if p.get("zfar") is not None:
        out["far"] = float(p["zfar"])
    return out


def _unit_normals(n: np.ndarray) -> np.ndarray | None:
    length = np.linalg.norm(n, axis=1, keepdims=True)
    if not np.all(np.isfinite(n)) or not np.all(length > 0):
        return None
    return n / length


def _tangents(tg: np.ndarray, world: np.ndarray) -> np.ndarray | None:
    """TANGENT (xyz, w) under the node's world matrix: xyz transforms as a surface direction, and
    w flips where the matrix mirrors (the bitangent w N x T must keep pointing along +v)."""
    tg = tg.astype(np.float64)
    xyz = tg[:, :3] @ world[:3, :3].T
    length = np.linalg.norm(xyz, axis=1, keepdims=True)
    if not np.all(np.isfinite(tg)) or not np.all(length > 0):
        return None
    w = np.where(tg[:, 3:] < 0, -1.0, 1.0) * np.sign(np.linalg.det(world[:3, :3]))
    return np.concatenate([xyz / length, w], 1)


def read(obj: SceneObject, base_dir: str | None, where: str) -> Expanded:
    """The scene objects, meshes and (if asked for) the camera of one glTF object."""
    spec = obj.mesh
    full = spec.path if os.path.isabs(spec.path) or base_dir is None else os.path.join(base_dir, spec.path)
    if not os.path.isfile(full):
        raise SceneError(f"{where}: glTF file not found: {full}")
    try:
        return _read(obj, full, where)
    except _Malformed as exc:
        raise SceneError(f"{where}: glTF file {full}: {exc}") from None
    except SceneError:   # already names the file and the primitive
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        # A field of the wrong JSON type or a missing required key deep inside the file.
        raise SceneError(f"{where}: glTF file {full} is malformed: {type(exc).__name__}: {exc}") from None


def _read(obj: SceneObject, full: str, where: str) -> Expanded:
    c = _Container(full)
    unsupported: set[str] = set()
    required = set(c.json.get("extensionsRequired", [])) - SUPPORTED_EXTENSIONS
    if required:
        raise _Malformed("extensionsRequired", f"needs {sorted(required)}, which this loader cannot read")
    unsupported |= set(c.json.get("extensionsUsed", [])) - SUPPORTED_EXTENSIONS
    for key, what in (("animations", "animations (use the scene file's motion)"), ("skins", "skins")):
        if c.json.get(key):
            unsupported.add(what)
    materials = _Materials(c, unsupported)
    placed = _walk(c)
    out = Expanded([], [], None)
    dropped = 0
    for ni, world in placed:
        node = c.json["nodes"][ni]
        if "mesh" not in node:
            continue
        if "skin" in node:
            unsupported.add("skins")
        mesh = c.item("meshes", node["mesh"], f"nodes[{ni}].mesh")
        label = f"{obj.name}:{node.get('name', 'node')}#{ni}"
        det = np.linalg.det(world[:3, :3])
        if not det:
            raise _Malformed(f"nodes[{ni}]", "world transform is singular (flattens its mesh)")
        for pi, p in enumerate(mesh["primitives"]):
            pwhere = f"meshes[{node['mesh']}].primitives[{pi}]"
            attr = p["attributes"]
            if "targets" in p:
                unsupported.add("morph targets")
            if any(k.startswith("COLOR_") for k in attr):
                unsupported.add("COLOR_0 vertex colours")
            if "POSITION" not in attr:
                raise _Malformed(f"{pwhere}.attributes", "has no POSITION")
            pos = c.accessor(attr["POSITION"], f"{pwhere}.attributes.POSITION", (3,)).astype(np.float64)
            faces = _faces(c, p, len(pos), pwhere)
            if faces is None:
                unsupported.add(f"primitive mode {_MODES.get(p.get('mode'), p.get('mode'))} (skipped)")
                continue
            if len(faces) == 0:
                continue
            mat, texcoord = materials.get(p.get("material"), f"{pwhere}.material")
            if mat is None:
                continue
            uv = None
            uv_key = f"TEXCOORD_{0 if texcoord is None else texcoord}"
            if uv_key in attr:
                uv = c.accessor(attr[uv_key], f"{pwhere}.attributes.{uv_key}", (2,)).astype(np.float64)
                uv[:, 1] = 1.0 - uv[:, 1]            # glTF's v runs down the image, ours up
            elif texcoord is not None:
                raise _Malformed(f"{pwhere}.attributes", f"material {p.get('material')} samples "
                                 f"{uv_key}, which the primitive does not have")
            normals = None
            if "NORMAL" in attr:
                n = c.accessor(attr["NORMAL"], f"{pwhere}.attributes.NORMAL", (3,)).astype(np.float64)
                normals = _unit_normals(n @ np.linalg.inv(world[:3, :3]))   # inverse transpose
                if normals is None:
                    unsupported.add("zero-length NORMALs (those primitives are flat shaded)")
            tangents = None
            if "TANGENT" in attr and mat.normal_map is not None:
                tangents = _tangents(c.accessor(attr["TANGENT"], f"{pwhere}.attributes.TANGENT", (4,)), world)
                if tangents is None:
                    unsupported.add("zero-length or non-finite TANGENTs (those primitives' tangents generated)")
            if len(pos) and (faces.max() >= len(pos)):
                raise _Malformed(f"{pwhere}.indices", f"index {int(faces.max())} >= {len(pos)} vertices")
            if det < 0:   # a mirroring transform reverses the winding
                faces = faces[:, ::-1]
            verts = pos @ world[:3, :3].T + world[:3, 3]
            for a, what in ((uv, "TEXCOORD"), (normals, "NORMAL"), (tangents, "TANGENT")):
                if a is not None and len(a) != len(pos):
                    raise _Malformed(f"{pwhere}.attributes.{what}", f"{len(a)} values for {len(pos)} vertices")
            # Real assets carry zero-area triangles (strip restarts, collapsed detail): they cover
            # no pixel, so they are dropped and counted in the one warning, not one per primitive.
            flat = degenerate_faces(verts, faces)
            if flat.any():
                dropped += int(flat.sum())
                faces = faces[~flat]
                if len(faces) == 0:
                    continue
            name = f"{label}.{pi}"
            m = MeshData(verts, np.ascontiguousarray(faces, np.int64), uv, normals, tangents)
            m.validate(f"{where} ({name}, {pwhere})")
            out.meshes.append(m)
            out.objects.append(SceneObject(name=name, mesh=MeshSpec(kind="arrays", vertices=verts, faces=m.faces,
                                                                        uvs=uv, normals=normals),
                                           material=mat, transform=obj.transform, motion=obj.motion))
    if not out.objects:
        raise _Malformed("meshes", "the scene has no triangle primitive left to draw")
    if dropped:
        unsupported.add(f"{dropped} zero-area triangles (dropped)")
    if obj.mesh.camera:
        out.camera = _camera(c, placed)
    out.digests = c.digests
    if unsupported:
        warnings.warn(f"{where}: glTF file {full}: not rendered: {'; '.join(sorted(unsupported))}",
                      SceneWarning, stacklevel=4)
    return out
