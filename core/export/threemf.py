"""3MF (3D Manufacturing Format) writer and reader: print-ready parts in mm, named and coloured.

A 3MF file is a zip package (Open Packaging Conventions) holding ``[Content_Types].xml``,
``_rels/.rels`` and the model part ``3D/3dmodel.model`` (3MF Consortium, *3MF Core
Specification* 1.3, 2022). :func:`write_3mf` writes core-spec only, no extensions:

* ``<model unit="millimeter">``, metadata ``Title`` and ``Application`` (well-known names) and
  ``anatomesh:space`` (``RAS``/``LPS``, the space the vertices are in) — vendor metadata needs a
  namespace prefix declared on ``<model>`` (spec §3.4.1), here ``xmlns:anatomesh`` = :data:`NS_ANATOMESH`;
* one ``<basematerials>`` group, one ``<base name=… displaycolor="#RRGGBB[AA]">`` per surface
  (``Mesh.color`` 0..1 taken as sRGB, as the label tables give it), and the same colours as a
  ``<m:colorgroup>`` (materials extension, not required: readers without it ignore it);
* the slicers' metadata parts that give each part its own filament in PrusaSlicer, Bambu
  Studio and OrcaSlicer (:mod:`.threemf_slicers`);
* one ``<object type="model" name=…>`` per surface referencing its material (``pid``/``pindex``),
  with the label value in the object's ``<metadatagroup>`` (``anatomesh:value``);
* one ``<build><item objectid=…/>`` per object, no transform: vertices are already in mm in the
  patient space (slicers move the parts onto their bed).

Vertices are written with 9 significant digits (like ``%.9g``, formatted by a numba kernel in
``_text_kernels.py``), which reads back to the very same float32 (9 digits always separate
neighbouring float32 values). The spec requires closed,
consistently outward-oriented manifold meshes for ``type="model"``; the label shells are.
"""
from __future__ import annotations

import re
import warnings
import zipfile
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple
from xml.parsers import expat
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from .common import atomic_write, check_meshes
from .threemf_slicers import (BAMBU_CONFIG, NS_MATERIAL, PRUSA_CONFIG, bambu_model_settings,
                              filament_numbers, prusa_model_config, xml_text)
from ..model.labels import rgba
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh

NS_CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
NS_ANATOMESH = "http://schemas.anatomesh.org/3mf/2026"
MODEL_PART = "3D/3dmodel.model"
REL_MODEL = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
#: rows formatted per string operation (bounds the memory of one chunk to a few MB)
CHUNK = 65536
#: zlib level for the model part: 1 compresses much faster than the default 6, for a somewhat
#: larger file
COMPRESSLEVEL = 1
UNIT_MM = {"micron": 0.001, "millimeter": 1.0, "centimeter": 10.0, "inch": 25.4, "foot": 304.8,
           "meter": 1000.0}

_CONTENT_TYPES = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
    '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
    '<Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
    '<Default Extension="config" ContentType="application/xml"/>'
    '</Types>\n')
#: resource ids: the base materials, the colour group, then one object per part
_COLOR_GROUP, _FIRST_OBJECT = 2, 3
_RELS = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
    f'<Relationship Target="/{MODEL_PART}" Id="rel0" Type="{REL_MODEL}"/>'
    '</Relationships>\n')


# ---------------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------------
def write_3mf(meshes: Sequence[Mesh], path, *, title: str = "",
              filaments: Optional[Sequence[int]] = None) -> Path:
    """Write all ``meshes`` into one 3MF package (one object per surface); returns the path.

    Every part gets its own filament in PrusaSlicer, Bambu Studio and OrcaSlicer (their
    metadata parts, :mod:`.threemf_slicers`): ``filaments`` (1-based, one per mesh) or by
    default one per distinct colour.

    Parameters
    ----------
    meshes : sequence of Mesh
        Closed surfaces, vertices (N, 3) float32 in mm, faces (M, 3) int32 outward (CCW).
        All in one ``space`` (``"RAS"`` or ``"LPS"``), recorded in the metadata.
    path : str or PathLike
        Output file (``.3mf``); written to ``path + '.part'`` and renamed when complete.
    title : str
        The package's ``Title`` metadata (default: the file name's stem).
    filaments : sequence of int, optional
        The filament (extruder) number of each mesh, from 1.

    Raises
    ------
    AnatomeshError
        For an empty list, mixed or unknown spaces, a mesh without triangles, NaN/infinite
        vertices, face indices out of range, a triangle with a repeated vertex (3MF forbids it),
        or an unwritable path.
    """

    path = Path(path)
    meshes = check_meshes(meshes, path, "3MF")
    for m in meshes:
        f = m.faces
        if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])):
            raise AnatomeshError(f"surface {m.name!r} has triangles with a repeated vertex, which "
                                 f"3MF forbids; clean the mesh (drop degenerate faces) first", path)
    colours = [_hex_color(m.color)[:7] for m in meshes]
    fil = list(filaments) if filaments is not None else filament_numbers(meshes, colours)
    if len(fil) != len(meshes) or any(int(x) < 1 for x in fil):
        raise AnatomeshError(f"give one filament number (1, 2, ...) per part: {len(meshes)} parts, "
                             f"filaments {fil}", path)
    ids = [k + _FIRST_OBJECT for k in range(len(meshes))]
    big = sum(55 * m.n_vertices + 50 * m.n_faces for m in meshes) > 2 ** 31 - 2 ** 26
    with atomic_write(path) as fh:
        with zipfile.ZipFile(fh, "w", zipfile.ZIP_DEFLATED, compresslevel=COMPRESSLEVEL) as zf:
            zf.writestr("[Content_Types].xml", _CONTENT_TYPES)
            zf.writestr("_rels/.rels", _RELS)
            with zf.open(MODEL_PART, "w", force_zip64=big) as out:
                for chunk in _model_xml(meshes, title or path.stem):
                    out.write(chunk if isinstance(chunk, bytes) else chunk.encode("utf-8"))
            zf.writestr(PRUSA_CONFIG, prusa_model_config(meshes, ids, fil))
            zf.writestr(BAMBU_CONFIG, bambu_model_settings(meshes, ids, fil))
    return path


def _text(s) -> str:
    return xml_text(s)


def _hex_color(color) -> str:
    r, g, b, a = (int(round(c * 255)) for c in rgba(color))
    return f"#{r:02X}{g:02X}{b:02X}" + (f"{a:02X}" if a < 255 else "")


def _model_xml(meshes: List[Mesh], title: str):
    """The model part as a sequence of chunks (str for markup, bytes for the number rows)."""
    space = meshes[0].space
    yield ('<?xml version="1.0" encoding="UTF-8"?>\n'
           f'<model unit="millimeter" xml:lang="en-US" xmlns="{NS_CORE}" xmlns:m="{NS_MATERIAL}" '
           f'xmlns:anatomesh="{NS_ANATOMESH}">\n'
           f' <metadata name="Title">{escape(_text(title))}</metadata>\n'
           ' <metadata name="Application">Anatomesh</metadata>\n'
           f' <metadata name="anatomesh:space">{escape(_text(space))}</metadata>\n'
           ' <resources>\n  <basematerials id="1">\n')
    for m in meshes:
        name = quoteattr(_text(m.name or "surface"))
        yield f'   <base name={name} displaycolor="{_hex_color(m.color)}"/>\n'
    yield f'  </basematerials>\n  <m:colorgroup id="{_COLOR_GROUP}">\n'
    for m in meshes:
        yield f'   <m:color color="{_hex_color(m.color)}"/>\n'
    yield "  </m:colorgroup>\n"
    for k, m in enumerate(meshes):
        yield (f'  <object id="{k + _FIRST_OBJECT}" type="model" '
               f'name={quoteattr(_text(m.name or "surface"))} pid="1" pindex="{k}">\n')
        if m.value is not None:
            yield ('   <metadatagroup><metadata name="anatomesh:value">'
                   f'{escape(_text(m.value))}</metadata></metadatagroup>\n')
        yield "   <mesh>\n    <vertices>\n"
        yield from _rows('     <vertex x="{}" y="{}" z="{}"/>\n', m.vertices)
        yield "    </vertices>\n    <triangles>\n"
        yield from _rows('     <triangle v1="{}" v2="{}" v3="{}"/>\n', m.faces)
        yield "    </triangles>\n   </mesh>\n  </object>\n"
    yield " </resources>\n <build>\n"
    for k in range(len(meshes)):
        yield f'  <item objectid="{k + _FIRST_OBJECT}"/>\n'
    yield " </build>\n</model>\n"


def _rows(template: str, a: np.ndarray):
    """Each row of ``a`` formatted into ``template`` (``{}`` marks a number), CHUNK rows per
    bytes chunk: 9 significant digits for floats, decimal for ints (numba kernels)."""
    from . import _threemf_kernels as K

    parts = template.split("{}")
    tpl = np.frombuffer("".join(parts).encode("ascii"), np.uint8)
    cuts = np.cumsum([0] + [len(x) for x in parts]).astype(np.int64)
    is_float = a.dtype.kind == "f"
    a = a.astype(np.float64 if is_float else np.int64).reshape(len(a), -1)
    if a.shape[1] != len(parts) - 1:  # the kernels trust the cuts: never let them overrun
        raise ValueError(f"template has {len(parts) - 1} fields for {a.shape[1]} columns")
    width = len(tpl) + a.shape[1] * K.MAX_NUMBER_BYTES
    buf = np.empty(min(len(a), CHUNK) * width, np.uint8)
    for i in range(0, len(a), CHUNK):
        c = np.ascontiguousarray(a[i:i + CHUNK])
        n = (K.float_rows if is_float else K.uint_rows)(c, tpl, cuts, buf)
        yield buf[:n].tobytes()


# ---------------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------------
def read_3mf(path) -> List[Mesh]:
    """Read the parts of a 3MF file: one :class:`Mesh` per build item, in mm.

    Reads core-spec models from Anatomesh and other producers: the unit is converted to mm,
    build-item and component transforms are applied (components flattened into one mesh per
    item, triangles flipped under a mirroring transform), colours come from the object's (or its
    first triangle's) ``<basematerials>`` entry, names from the object. ``space`` comes from our
    ``anatomesh:space`` metadata (``"RAS"`` when absent) and ``value`` from ``anatomesh:value``.
    Untransformed vertices read back exactly as written.

    Raises
    ------
    AnatomeshError
        When the file is not a readable 3MF package or its model is malformed.
    """
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as zf:
            data = zf.read(_model_part_name(zf))
    except (OSError, zipfile.BadZipFile, KeyError) as exc:
        raise AnatomeshError(f"not a readable 3MF package ({exc}); export it again as 3MF", path) from None
    p = _ModelParser()
    try:
        p.parse(data)
    except (expat.ExpatError, ValueError, KeyError, IndexError) as exc:
        raise AnatomeshError(f"malformed 3MF model ({exc}); re-export the file", path) from None
    return p.meshes(path)


def _model_part_name(zf: zipfile.ZipFile) -> str:
    """The 3D model part named by the package relationships (``/3D/3dmodel.model`` usually)."""
    try:
        rels = zf.read("_rels/.rels").decode("utf-8", "replace")
    except KeyError:
        rels = ""
    for m in re.finditer(r"<Relationship\b[^>]*>", rels):
        tag = m.group(0)
        if REL_MODEL in tag:
            t = re.search(r'Target\s*=\s*"([^"]+)"', tag)
            if t:
                return t.group(1).lstrip("/")
    return MODEL_PART


def _matrix(text: Optional[str]) -> Optional[np.ndarray]:
    """3MF ``ST_Matrix3D`` (12 numbers, row vectors: p' = p @ M[:3] + M[3]) as (4, 3) float64."""
    if not text:
        return None
    vals = [float(x) for x in text.split()]
    if len(vals) != 12:
        raise ValueError(f"transform needs 12 numbers, got {len(vals)}")
    return np.array(vals).reshape(4, 3)


def _compose(inner: Optional[np.ndarray], outer: Optional[np.ndarray]) -> Optional[np.ndarray]:
    """The transform ``outer`` applied after ``inner`` (either may be None = identity)."""
    if inner is None:
        return outer
    if outer is None:
        return inner
    out = np.empty((4, 3))
    out[:3] = inner[:3] @ outer[:3]
    out[3] = inner[3] @ outer[:3] + outer[3]
    return out


_OPEN = re.compile(rb"<((?:[\w.-]+:)?)(vertices|triangles)\b[^>]*?(/?)>")
_FIRST_TRIANGLE = re.compile(rb"<(?:[\w.-]+:)?triangle\b[^>]*>")
_ROW = {b"vertices": (b"vertex", ("x", "y", "z"), float),
        b"triangles": (b"triangle", ("v1", "v2", "v3"), int)}


def _attr_values(block: bytes, name: str, cast) -> List:
    """Values of attribute ``name`` of every element in ``block``, in order."""
    return [cast(v) for v in re.findall(rb"\s" + name.encode() + rb"\s*=\s*[\"']([^\"']*)[\"']", block)]


def _fast_rows(block: bytes, names) -> Optional[np.ndarray]:
    """The block's numbers (n, 3) float64 parsed in C (``np.fromstring``) when every element is
    ``<elem a="…" b="…" c="…"/>`` with exactly ``names`` in this order (checked with numpy at
    every ``=``); None for any other form."""
    a = np.frombuffer(block, np.uint8)
    eq = np.flatnonzero(a == ord("="))
    n = block.count(b"<")
    if n == 0 or len(eq) != 3 * n:
        return None
    at = eq.reshape(-1, 3)
    for j, name in enumerate(names):
        for k, ch in enumerate(reversed(name.encode())):
            if not np.all(a[at[:, j] - 1 - k] == ch):
                return None
        if not np.all(np.isin(a[at[:, j] - 1 - len(name)], (9, 10, 13, 32))):
            return None
    quote = a == ord('"')
    inside = np.bitwise_xor.accumulate(quote.view(np.uint8)).view(bool) & ~quote
    text = np.where(inside, a, np.uint8(32)).tobytes()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vals = np.fromstring(text, sep=" ")
    return vals.reshape(-1, 3) if vals.size == 3 * n else None


def _bulk_block(kind: bytes, block: bytes):
    """(array (n, 3), first triangle's (pid, p1) or None) of a ``<vertices>``/``<triangles>``
    block, read in bulk: far faster than one parser callback per element. The plain form
    (``<vertex x= y= z=/>``, ``<triangle v1= v2= v3=/>``) is parsed by numpy; anything else
    (other attribute orders, per-triangle properties, prefixes) by regular expressions."""
    elem, names, cast = _ROW[kind]
    arr = _fast_rows(block, names)
    if arr is not None:
        arr = arr if cast is float else arr.astype(np.int64)
    else:
        arr = _slow_rows(block, elem, names, cast)
    first = None
    if kind == b"triangles":
        m = _FIRST_TRIANGLE.search(block)
        tag = m.group(0).decode("utf-8", "replace") if m else ""
        pid = re.search(r'\spid\s*=\s*"([^"]*)"', tag)
        p1 = re.search(r'\sp1\s*=\s*"([^"]*)"', tag)
        first = (pid.group(1), p1.group(1) if p1 else "0") if pid else None
    return arr, first


def _slow_rows(block: bytes, elem: bytes, names, cast) -> np.ndarray:
    """Rows of a block in any attribute order or with namespace prefixes (regex per row)."""
    n = len(re.findall(rb"<(?:[\w.-]+:)?" + elem + rb"\b", block))
    q = rb"\s*=\s*\"([^\"]*)\""
    row = rb"<(?:[\w.-]+:)?" + elem + b"".join(rb"\s+" + c.encode() + q for c in names)
    rows = re.findall(row, block)
    if len(rows) == n:
        flat = [cast(x) for r in rows for x in r]
    else:
        cols = [_attr_values(block, c, cast) for c in names]
        if any(len(c) != n for c in cols):
            raise ValueError(f"every <{elem.decode()}> needs exactly one each of {', '.join(names)}")
        flat = [x for r in zip(*cols) for x in r]
    return np.array(flat, np.float64 if cast is float else np.int64).reshape(-1, 3)


def _split_bulk(data: bytes):
    """``data`` with every vertices/triangles block emptied, and the blocks' arrays in order."""
    out, bulk, pos, start = [], [], 0, 0
    while True:
        m = _OPEN.search(data, pos)
        if m is None:
            break
        pos = m.end()
        if m.group(3):  # <vertices/>
            continue
        close = data.find(b"</" + m.group(1) + m.group(2), pos)
        if close < 0:
            raise ValueError(f"<{m.group(2).decode()}> is not closed")
        bulk.append(_bulk_block(m.group(2), data[pos:close]))
        out.append(data[start:pos])
        start = pos = close
    out.append(data[start:])
    return b"".join(out), bulk


class _Object:
    def __init__(self, attrs: Dict[str, str]):
        self.name = attrs.get("name", "")
        self.pid = attrs.get("pid")
        self.pindex = attrs.get("pindex")
        self.vertices: List = []  # float arrays (n, 3) or single coordinates
        self.triangles: List = []  # int arrays (m, 3) or single indices
        self.components: List[Tuple[str, Optional[np.ndarray]]] = []
        self.value: Optional[str] = None


class _ModelParser:
    """Forward-only (expat) parse of a core-spec model part."""

    def __init__(self):
        self.unit = "millimeter"
        self.metadata: Dict[str, str] = {}
        self.materials: Dict[str, List[str]] = {}  # basematerials id → displaycolors
        self.objects: Dict[str, _Object] = {}
        self.items: List[Tuple[str, Optional[np.ndarray]]] = []
        self.prefixes: Dict[str, str] = {}
        self._obj: Optional[_Object] = None
        self._group: Optional[str] = None
        self._meta: Optional[str] = None
        self._chars: List[str] = []
        self._bulk: List = []

    def parse(self, data: bytes) -> None:
        data, self._bulk = _split_bulk(data)
        self._bulk.reverse()
        px = expat.ParserCreate(namespace_separator=" ")
        px.buffer_text = True
        px.StartElementHandler = self._start
        px.EndElementHandler = self._end
        px.CharacterDataHandler = self._char
        px.StartNamespaceDeclHandler = lambda prefix, uri: self.prefixes.__setitem__(prefix or "", uri)
        px.Parse(data, True)

    def _start(self, tag: str, a: Dict[str, str]) -> None:
        ns, _, name = tag.rpartition(" ")
        if ns != NS_CORE:
            return
        o = self._obj
        if name in ("vertices", "triangles") and self._bulk:
            arr, first = self._bulk.pop()
            (o.vertices if name == "vertices" else o.triangles).append(arr)
            if first is not None and o.pid is None:
                o.pid, o.pindex = first
        elif name == "vertex":
            o.vertices.append(np.array([[float(a["x"]), float(a["y"]), float(a["z"])]]))
        elif name == "triangle":
            o.triangles.append(np.array([[int(a["v1"]), int(a["v2"]), int(a["v3"])]]))
            if o.pid is None and "pid" in a:  # no object-level material: the first triangle's
                o.pid, o.pindex = a["pid"], a.get("p1", "0")
        elif name == "object":
            self._obj = _Object(a)
            self.objects[a["id"]] = self._obj
        elif name == "component":
            o.components.append((a["objectid"], _matrix(a.get("transform"))))
        elif name == "item":
            self.items.append((a["objectid"], _matrix(a.get("transform"))))
        elif name == "basematerials":
            self._group = a["id"]
            self.materials[self._group] = []
        elif name == "base":
            self.materials[self._group].append(a.get("displaycolor", ""))
        elif name == "metadata":
            self._meta, self._chars = self._qname(a.get("name", "")), []
        elif name == "model":
            self.unit = a.get("unit", "millimeter")

    def _qname(self, name: str) -> str:
        prefix, _, local = name.rpartition(":")
        return f"{{{self.prefixes.get(prefix, prefix)}}}{local}" if prefix else local

    def _end(self, tag: str) -> None:
        ns, _, name = tag.rpartition(" ")
        if ns != NS_CORE:
            return
        if name == "metadata" and self._meta is not None:
            text = "".join(self._chars)
            if self._obj is not None and self._meta == f"{{{NS_ANATOMESH}}}value":
                self._obj.value = text
            elif self._obj is None:
                self.metadata[self._meta] = text
            self._meta = None
        elif name == "object":
            self._obj = None

    def _char(self, text: str) -> None:
        if self._meta is not None:
            self._chars.append(text)

    # -- assembling meshes --------------------------------------------------------------------
    def meshes(self, path) -> List[Mesh]:
        if self.unit not in UNIT_MM:
            raise AnatomeshError(f"unknown 3MF unit {self.unit!r}", path)
        scale = UNIT_MM[self.unit]
        space = self.metadata.get(f"{{{NS_ANATOMESH}}}space", "RAS")
        space = space if space in ("RAS", "LPS") else "RAS"
        out = []
        for oid, transform in self.items:
            if oid not in self.objects:
                raise AnatomeshError(f"build item refers to missing object {oid}", path)
            obj = self.objects[oid]
            parts = self._flatten(oid, transform, 0)
            if not parts:
                continue
            vs, fs, color, n = [], [], None, 0
            for v, f, c in parts:
                vs.append(v)
                fs.append(f + n)
                n += len(v)
                color = color or c
            v = np.concatenate(vs)
            if scale != 1.0:
                v = v * scale
            out.append(Mesh(v.astype(np.float32), np.concatenate(fs), name=obj.name,
                            value=_number(obj.value), color=color or (0.8, 0.8, 0.8), space=space,
                            meta={"source": str(path), "object_id": oid}))
        return out

    def _flatten(self, oid: str, transform: Optional[np.ndarray], depth: int):
        """[(vertices float64 (N,3), faces int32 (M,3), colour or None)] of object ``oid``."""
        if depth > 32 or oid not in self.objects:
            raise ValueError(f"component reference to object {oid} is missing or circular")
        o = self.objects[oid]
        out = []
        if o.vertices:
            v = np.concatenate(o.vertices).astype(np.float64)
            f = np.concatenate(o.triangles or [np.zeros((0, 3), np.int64)]).astype(np.int64)
            if f.size and (f.min() < 0 or f.max() >= len(v)):
                raise ValueError(f"object {oid} has triangle indices outside its vertices")
            if transform is not None:
                v = v @ transform[:3] + transform[3]
                if np.linalg.det(transform[:3]) < 0:
                    f = f[:, ::-1]
            out.append((v, np.ascontiguousarray(f, np.int32), self._color(o)))
        for cid, ct in o.components:
            out += self._flatten(cid, _compose(ct, transform), depth + 1)
        return out

    def _color(self, o: _Object):
        group = self.materials.get(o.pid or "")
        try:
            text = group[int(o.pindex or 0)]
        except (TypeError, IndexError, ValueError):
            return None
        return _parse_color(text)


def _parse_color(text: str):
    """``#RRGGBB`` or ``#RRGGBBAA`` → (r, g, b) or (r, g, b, a) floats 0..1 (None if invalid)."""
    t = text.strip().lstrip("#")
    if len(t) not in (6, 8) or not re.fullmatch(r"[0-9A-Fa-f]+", t):
        return None
    c = tuple(int(t[i:i + 2], 16) / 255.0 for i in range(0, len(t), 2))
    return c if len(c) == 3 or c[3] < 1.0 else c[:3]


def _number(text: Optional[str]):
    if text is None:
        return None
    try:
        x = float(text)
    except ValueError:
        return None
    return int(x) if x.is_integer() else x
