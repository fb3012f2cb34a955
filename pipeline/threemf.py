"""A part as a 3MF file with the print settings it assumes (issue #26 item 5: ``best.3mf``).

Written here from the 3MF core specification (a zip of three XML parts: ``[Content_Types].xml``,
``_rels/.rels`` and the model ``3D/3dmodel.model``, unit millimetre) rather than by trimesh's
3MF exporter: that one writes no metadata and no slicer config (so it cannot carry the print
settings), and it and trimesh's 3MF loader need lxml and networkx, which flexopt does not
install. The spec is small and the writer is the standard library's zipfile and XML escaping.

What the file holds:

- the mesh (vertices in mm, full float precision, so its volume is the STL's), one object, one
  build item, laid as given (the pipeline gives the part laid flat on the bed, as best.stl);
- ``<metadata>``: the spec's ``Title``, ``Designer``, ``Description``, ``Application`` and
  ``CreationDate``, and each print setting as ``flexopt:NAME`` (names outside the spec's list
  must carry a namespace; :data:`NAMESPACE` is ours, an identifier only);
- ``Metadata/Slic3r_PE.config``: the settings in PrusaSlicer's names (``; key = value`` lines,
  the file PrusaSlicer writes into its own 3MF projects), which it and its forks read on import;
  a slicer takes every setting not named from its profile.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Mapping
from datetime import date
from xml.sax.saxutils import escape, quoteattr

import numpy as np

__all__ = ["NAMESPACE", "CORE", "SLICER_CONFIG", "threemf_bytes", "read_threemf"]

#: The 3MF core namespace (the 2015/02 core specification).
CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
#: flexopt's metadata namespace (a URN: an identifier, nothing is fetched from it).
NAMESPACE = "urn:flexopt:print-settings:1"
#: PrusaSlicer's project config inside a 3MF.
SLICER_CONFIG = "Metadata/Slic3r_PE.config"
MODEL = "3D/3dmodel.model"

_CONTENT_TYPES = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
    '<Default Extension="rels" '
    'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
    '<Default Extension="model" '
    'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
    '<Default Extension="config" ContentType="text/plain"/>'
    "</Types>\n"
)
_RELS = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
    f'<Relationship Target="/{MODEL}" Id="rel0" '
    'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>'
    "</Relationships>\n"
)


def threemf_bytes(
    vertices: np.ndarray,
    faces: np.ndarray,
    title: str,
    settings: Mapping[str, str],
    slicer: Mapping[str, str] | None = None,
    description: str = "",
) -> bytes:
    """A 3MF file of one mesh with its print settings.

    Parameters
    ----------
    vertices : (n, 3) float, mm
    faces : (m, 3) int — counter-clockwise seen from outside (as trimesh's).
    title : str — the part's name (the object's and the file's Title).
    settings : mapping of str to str — written as ``flexopt:NAME`` metadata.
    slicer : mapping of str to str, optional — ``Metadata/Slic3r_PE.config``.
    description : str — the file's Description.

    Returns
    -------
    bytes
        The zip.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or not len(f):
        raise ValueError("a 3MF mesh needs (n, 3) vertices and at least one (m, 3) face")
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError("a 3MF face refers to a vertex that is not there")
    meta = {
        "Title": title,
        "Designer": "flexopt",
        "Application": "flexopt",
        "Description": description,
        "CreationDate": date.today().isoformat(),
    }
    out = io.StringIO()
    out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
    out.write(
        f'<model unit="millimeter" xml:lang="en-US" xmlns="{CORE}" xmlns:flexopt="{NAMESPACE}">\n'
    )
    for name, text in meta.items():
        out.write(f"  <metadata name={quoteattr(name)}>{escape(text)}</metadata>\n")
    for name, text in settings.items():
        out.write(
            f'  <metadata name={quoteattr("flexopt:" + name)} preserve="1">'
            f"{escape(str(text))}</metadata>\n"
        )
    out.write(f'  <resources>\n    <object id="1" type="model" name={quoteattr(title)}>\n')
    out.write("      <mesh>\n        <vertices>\n")
    # repr of a float is its shortest exact form: the 3MF's volume is the mesh's to the last bit
    out.writelines(f'          <vertex x="{x!r}" y="{y!r}" z="{z!r}"/>\n' for x, y, z in v.tolist())
    out.write("        </vertices>\n        <triangles>\n")
    out.writelines(f'          <triangle v1="{a}" v2="{b}" v3="{c}"/>\n' for a, b, c in f.tolist())
    out.write("        </triangles>\n      </mesh>\n    </object>\n  </resources>\n")
    out.write('  <build>\n    <item objectid="1"/>\n  </build>\n</model>\n')
    buf = io.BytesIO()
    # fixed timestamps: the same part gives the same bytes (the zip records each member's date)
    stamp = (1980, 1, 1, 0, 0, 0)
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        members = [("[Content_Types].xml", _CONTENT_TYPES), ("_rels/.rels", _RELS)]
        members.append((MODEL, out.getvalue()))
        if slicer:
            members.append(
                (
                    SLICER_CONFIG,
                    "; the print settings the flexopt design assumes (the rest: the profile's)\n"
                    + "".join(f"; {k} = {val}\n" for k, val in slicer.items()),
                )
            )
        for name, text in members:
            info = zipfile.ZipInfo(name, stamp)
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, text.encode("utf-8"))
    return buf.getvalue()


def read_threemf(data: bytes) -> tuple[np.ndarray, np.ndarray, dict[str, str], dict[str, str]]:
    """Read back a 3MF written by :func:`threemf_bytes` (the standard library's XML parser).

    Returns
    -------
    (vertices (n, 3) float mm, faces (m, 3) int, metadata {name: text}, slicer config
    {key: value})
    """
    import xml.etree.ElementTree as ET

    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        root = ET.fromstring(zf.read(MODEL))
        config = zf.read(SLICER_CONFIG).decode() if SLICER_CONFIG in zf.namelist() else ""
    ns = {"m": CORE}
    meta = {m.get("name", ""): m.text or "" for m in root.findall("m:metadata", ns)}
    mesh = root.find("m:resources/m:object/m:mesh", ns)
    if mesh is None:
        raise ValueError("the 3MF has no mesh")
    verts = np.array(
        [[float(e.get(k, "nan")) for k in "xyz"] for e in mesh.iterfind("m:vertices/m:vertex", ns)]
    )
    tris = np.array(
        [
            [int(e.get(k, "-1")) for k in ("v1", "v2", "v3")]
            for e in mesh.iterfind("m:triangles/m:triangle", ns)
        ],
        dtype=np.int64,
    )
    slicer = {}
    for line in config.splitlines():
        key, sep, value = line.removeprefix(";").partition("=")
        if sep:
            slicer[key.strip()] = value.strip()
    return verts, tris, meta, slicer
