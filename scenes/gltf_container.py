"""A glTF 2.0 file's JSON and binary buffers (.gltf with external or data-URI buffers, .glb):
accessors (normalised, sparse), buffer views and images, each checked as it is read."""
from __future__ import annotations

import base64
import hashlib
import io
import json
import os
import struct
import urllib.parse

import numpy as np

_COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
# Dividers of the glTF spec's normalised integers (signed ones clamp at -1).
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_MODES = {0: "POINTS", 1: "LINES", 2: "LINE_LOOP", 3: "LINE_STRIP"}
_WRAP = {33071: "CLAMP_TO_EDGE", 33648: "MIRRORED_REPEAT"}
_LINEAR = {9729, 9985, 9986, 9987}
# Extensions whose content is read, or which change nothing the study renders.
SUPPORTED_EXTENSIONS = {"KHR_mesh_quantization", "KHR_materials_emissive_strength", "EXT_texture_webp"}


class _Malformed(Exception):
    """A structural problem; `where` is the JSON path inside the glTF file."""

    def __init__(self, where: str, msg: str):
        super().__init__(f"{where}: {msg}")



class _Container:
    """The JSON and the binary buffers of one glTF file."""

    def __init__(self, full: str):
        self.full, self.dir = full, os.path.dirname(full)
        self.digests: list[str] = []
        with open(full, "rb") as fh:
            raw = fh.read()
        self.digests.append(hashlib.sha256(raw).hexdigest())
        bin_chunk = None
        if raw[:4] == b"glTF":
            self.json, bin_chunk = self._glb(raw)
        else:
            try:
                self.json = json.loads(raw.decode("utf-8-sig"))
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise _Malformed("(file)", f"neither a GLB nor glTF JSON: {exc}") from None
        if not isinstance(self.json, dict):
            raise _Malformed("(top level)", "the JSON is not an object")
        version = str(self.json.get("asset", {}).get("version", ""))
        if not version.startswith("2."):
            raise _Malformed("asset.version", f"only glTF 2.x is supported, got {version!r}")
        self.buffers = []
        for i, b in enumerate(self.json.get("buffers", [])):
            if "uri" in b:
                data = self.uri_bytes(b["uri"], f"buffers[{i}].uri")
            elif i == 0 and bin_chunk is not None:
                data = bin_chunk
            else:
                raise _Malformed(f"buffers[{i}]", "has no uri and is not the GLB's binary chunk")
            if len(data) < b.get("byteLength", 0):
                raise _Malformed(f"buffers[{i}]", f"byteLength {b['byteLength']} but {len(data)} bytes")
            self.buffers.append(data)

    @staticmethod
    def _glb(raw: bytes):
        if len(raw) < 20:
            raise _Malformed("(GLB header)", f"file of {len(raw)} bytes is truncated")
        _, version, length = struct.unpack_from("<4sII", raw)
        if version != 2:
            raise _Malformed("(GLB header)", f"GLB version {version}, only 2 is supported")
        if length > len(raw):
            raise _Malformed("(GLB header)", f"declares {length} bytes, the file has {len(raw)}")
        pos, doc, binary = 12, None, None
        while pos + 8 <= length:
            size, kind = struct.unpack_from("<II", raw, pos)
            body = raw[pos + 8:pos + 8 + size]
            if len(body) != size:
                raise _Malformed("(GLB chunk)", f"chunk at byte {pos} is truncated")
            if kind == 0x4E4F534A and doc is None:
                try:
                    doc = json.loads(body.decode("utf-8"))
                except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                    raise _Malformed("(GLB JSON chunk)", f"cannot parse: {exc}") from None
            elif kind == 0x004E4942 and binary is None:
                binary = body
            pos += 8 + size + (-size % 4)
        if doc is None:
            raise _Malformed("(GLB)", "has no JSON chunk")
        return doc, binary

    def uri_bytes(self, uri: str, where: str) -> bytes:
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            try:
                return base64.b64decode(payload, validate=True) if head.endswith(";base64") \
                    else urllib.parse.unquote_to_bytes(payload)
            except ValueError as exc:
                raise _Malformed(where, f"bad data URI: {exc}") from None
        path = os.path.join(self.dir, urllib.parse.unquote(uri))
        if not os.path.isfile(path):
            raise _Malformed(where, f"file not found: {path}")
        with open(path, "rb") as fh:
            data = fh.read()
        self.digests.append(hashlib.sha256(data).hexdigest())
        return data

    def item(self, kind: str, index, where: str) -> dict:
        items = self.json.get(kind, [])
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise _Malformed(where, f"{kind} index {index!r} out of range (the file has {len(items)})")
        return items[index]

    def view(self, index: int, where: str) -> tuple[bytes, int | None]:
        v = self.item("bufferViews", index, where)
        self.item("buffers", v["buffer"], f"bufferViews[{index}].buffer")
        buf = self.buffers[v["buffer"]]
        start, length = v.get("byteOffset", 0), v["byteLength"]
        if start + length > len(buf):
            raise _Malformed(f"bufferViews[{index}]", f"bytes {start}..{start + length} past the end "
                             f"of buffer {v['buffer']} ({len(buf)} bytes)")
        return buf[start:start + length], v.get("byteStride")

    def _read(self, view: int, offset: int, count: int, comp: int, width: int, where: str) -> np.ndarray:
        if comp not in _COMPONENT:
            raise _Malformed(where, f"componentType {comp} is not a glTF component type")
        dt = np.dtype(_COMPONENT[comp])
        data, stride = self.view(view, where)
        stride = stride or dt.itemsize * width
        need = offset + (count - 1) * stride + dt.itemsize * width if count else 0
        if need > len(data):
            raise _Malformed(where, f"{count} elements need {need} bytes of bufferView {view}, "
                             f"which has {len(data)}")
        if count == 0:
            return np.zeros((0, width), dt)
        return np.ndarray((count, width), dt, data, offset, (stride, dt.itemsize)).copy()

    def accessor(self, index, where: str, widths: tuple[int, ...]) -> np.ndarray:
        """(count, width) array; normalised integers become floats as the spec defines them."""
        a = self.item("accessors", index, where)
        where = f"accessors[{index}]"
        width = _WIDTH.get(a.get("type"))
        if width not in widths:
            raise _Malformed(where, f"type {a.get('type')!r} where {widths} components are expected")
        comp, count = a["componentType"], a["count"]
        if "bufferView" in a:
            out = self._read(a["bufferView"], a.get("byteOffset", 0), count, comp, width, where)
        else:
            out = np.zeros((count, width), np.dtype(_COMPONENT.get(comp, "<f4")))
        if "sparse" in a:
            s = a["sparse"]
            idx = self._read(s["indices"]["bufferView"], s["indices"].get("byteOffset", 0), s["count"],
                             s["indices"]["componentType"], 1, f"{where}.sparse.indices")[:, 0]
            if len(idx) and idx.max() >= count:
                raise _Malformed(f"{where}.sparse.indices", f"index {int(idx.max())} >= count {count}")
            out[idx.astype(np.int64)] = self._read(s["values"]["bufferView"], s["values"].get("byteOffset", 0),
                                                   s["count"], comp, width, f"{where}.sparse.values")
        if a.get("normalized") and comp in _NORM:
            return np.maximum(out.astype(np.float64) / _NORM[comp], -1.0)
        return out

    def image_rgba(self, index: int, where: str) -> np.ndarray:
        from PIL import Image
        img = self.item("images", index, where)
        where = f"images[{index}]"
        if "uri" in img:
            data = self.uri_bytes(img["uri"], f"{where}.uri")
        elif "bufferView" in img:
            data = self.view(img["bufferView"], f"{where}.bufferView")[0]
        else:
            raise _Malformed(where, "has neither uri nor bufferView")
        try:
            with Image.open(io.BytesIO(data)) as im:
                return np.asarray(im.convert("RGBA"))
        except Exception as exc:   # Pillow raises several types for undecodable data
            raise _Malformed(where, f"cannot decode the image: {exc}") from None
