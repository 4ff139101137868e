"""ParaView files of one solved scenario: OUT.vtm, a multiblock of

- OUT.vtu, the volume mesh (triangles lifted to z = 0, or tetrahedra): point data
  "displacement [m]" (a vector) and "temperature [K]" where thermal; cell data "stress [Pa]"
  (the Cauchy tensor, 9 components XX XY XZ YX YY YZ ZX ZY ZZ: ParaView's tensor), "von Mises
  stress [Pa]", "principal stress k [Pa]" (largest first), "shear stress intensity I2^2 [Pa^2]",
  and "body" / "region" as integers;
- OUT-contact.vtu, where the scene has contacts: the slave sides' facets (lines in 2D, triangles
  in 3D) on the contact nodes, in the order of the results file's `contact_node`, with point data
  "contact pressure [Pa]", "gap [m]", "slip [m]" and "shear traction [Pa]" (vectors
  Σ_k c_k t_k over the node's tangents t_k), the results file's tangential components themselves
  ("slip along tangents [m]", "shear traction along tangents [Pa]"), "normal" (the slave
  side's unit normal), "displacement [m]" of the node (to warp it with the volume) and "contact"
  (an integer).

Each file's field data is the name table of its integers: an array "body: NAME" (or "region:",
"contact:") holding its index, as ParaView lists field data by name. Written by hand (VTK XML,
zlib-compressed base64 binary, UInt64 headers): meshio writes neither field data nor component
names.
"""
from __future__ import annotations

import base64
import os
import zlib
from pathlib import Path

import numpy as np

from ..model.fields import Data


VTK_LINE, VTK_TRIANGLE, VTK_TETRA = 3, 5, 10
TENSOR = ("XX", "XY", "XZ", "YX", "YY", "YZ", "ZX", "ZY", "ZZ")
_TYPES = {"Float64": "<f8", "Int64": "<i8", "UInt8": "u1"}
BLOCK = 1 << 15                  # bytes of each zlib block (VTK's default)
LEVEL = 1                        # zlib's fastest level: 3.5x faster than its default 6, 4 % larger (the
#                                  fields of the 3D block patch at face 0.02, 7.9 MB)


_ESCAPES = str.maketrans({"&": "&amp;", "<": "&lt;", ">": "&gt;", "\n": "&#10;", "\r": "&#13;", "\t": "&#9;"})


def quoteattr(text: str) -> str:
    """`text` as a quoted XML attribute value, by the rule of xml.sax.saxutils.quoteattr (whose
    import loads urllib, http and ssl, 8 MB): in double quotes, in single ones when it holds a
    double quote and no single one, else with the double quotes escaped."""
    text = text.translate(_ESCAPES)
    if '"' not in text:
        return f'"{text}"'
    if "'" not in text:
        return f"'{text}'"
    return '"' + text.replace('"', "&quot;") + '"'


def _lift(v: np.ndarray) -> np.ndarray:
    """(n, 2) plane vectors as (n, 3) with z = 0; (n, 3) unchanged."""
    return v if v.shape[1] == 3 else np.column_stack([v, np.zeros(len(v))])


def stress_tensor(stress: np.ndarray, components) -> np.ndarray:
    """(n, 9) the full Cauchy tensor, row by row, from the results file's components (2D: xx yy
    zz xy, the plane's xz = yz = 0; 3D: xx yy zz yz xz xy)."""
    s = dict(zip(map(str, components), stress.T))
    zero = np.zeros(len(stress))
    xy, yz, xz = s["xy"], s.get("yz", zero), s.get("xz", zero)
    return np.column_stack([s["xx"], xy, xz, xy, s["yy"], yz, xz, yz, s["zz"]])


def _names(kind: str, names) -> dict[str, np.ndarray]:
    """The name table of an integer array: {"kind: name": [index]}."""
    return {f"{kind}: {n}": np.array([i]) for i, n in enumerate(map(str, names))}


def volume(ds: Data) -> tuple:
    """(points, cells, VTK cell type, point data, cell data, field data) of the volume mesh."""
    points = _lift(ds["coords"].values)
    point_data = {"displacement [m]": _lift(ds["displacement"].values)}
    if "temperature" in ds:
        point_data["temperature [K]"] = ds["temperature"].values
    cell_data = {"stress [Pa]": stress_tensor(ds["stress"].values, ds["component"].values),
                 "von Mises stress [Pa]": ds["von_mises"].values}
    for k in range(ds["principal_stress"].shape[1]):
        cell_data[f"principal stress {k + 1} [Pa]"] = ds["principal_stress"].values[:, k]
    cell_data["shear stress intensity I2^2 [Pa^2]"] = ds["shear_stress_intensity"].values
    cell_data["body"], cell_data["region"] = ds["cell_body"].values, ds["cell_region"].values
    field_data = {**_names("body", ds["body"].values), **_names("region", ds["region"].values)}
    cells = ds["cells"].values
    return points, cells, VTK_TETRA if cells.shape[1] == 4 else VTK_TRIANGLE, point_data, cell_data, field_data


def contact_surface(ds: Data, zone, facets: np.ndarray) -> tuple:
    """(points, cells, VTK cell type, point data, cell data, field data) of the contact surface:
    `facets` (s, 2 or 3) the contact rows at the corners of each slave facet
    (`wcs.contact.zone.slave_segments`), the rows' fields those of the results file `ds`."""
    tangents = zone.tangents                                          # (m, d − 1, d)

    def vector(name: str) -> np.ndarray:                              # Σ_k c_k t_k
        return _lift(np.einsum("mk,mkd->md", ds[name].values.reshape(len(tangents), -1), tangents))
    point_data = {"contact pressure [Pa]": ds["contact_pressure"].values, "gap [m]": ds["contact_gap"].values,
                  "slip [m]": vector("contact_slip"), "shear traction [Pa]": vector("contact_shear"),
                  "slip along tangents [m]": ds["contact_slip"].values,
                  "shear traction along tangents [Pa]": ds["contact_shear"].values,
                  "normal": _lift(np.concatenate([p.normal for p in zone.pairs])),
                  "displacement [m]": _lift(ds["displacement"].values[zone.nodes]),
                  "contact": zone.contact_of_node}
    kind = VTK_LINE if facets.shape[1] == 2 else VTK_TRIANGLE
    return (_lift(ds["contact_coords"].values), facets, kind, point_data,
            {"contact": zone.contact_of_node[facets[:, 0]]}, _names("contact", zone.names))


def _compressed(raw: bytes) -> str:
    """VTK's compressed binary: base64 of the header (blocks, block size, last block's size, each
    block's compressed size; UInt64), then base64 of the zlib blocks, at zlib's fastest level."""
    blocks = [zlib.compress(raw[i:i + BLOCK], LEVEL) for i in range(0, len(raw), BLOCK)]
    last = len(raw) - (len(blocks) - 1) * BLOCK if blocks else 0
    header = np.array([len(blocks), BLOCK, last, *map(len, blocks)], dtype="<u8")
    return base64.b64encode(header.tobytes()).decode() + base64.b64encode(b"".join(blocks)).decode()


def _array(name: str, data: np.ndarray, extra: str = "", vtk_type: str | None = None) -> str:
    """One DataArray of little-endian values, compressed; Float64 or Int64 by the data's kind
    unless `vtk_type` says."""
    data = np.asarray(data)
    vtk_type = vtk_type or ("Float64" if data.dtype.kind == "f" else "Int64")
    raw = np.ascontiguousarray(data, dtype=_TYPES[vtk_type]).tobytes()
    comps = f' NumberOfComponents="{data.shape[1]}"' if data.ndim == 2 else ""
    text = _compressed(raw)
    return (f'<DataArray type="{vtk_type}" Name={quoteattr(name)}{comps}'
            f'{extra} format="binary">{text}</DataArray>\n')


def _components(name: str, data: np.ndarray) -> str:
    """ComponentName attributes of a 9-component tensor (ParaView shows XX … ZZ)."""
    if np.ndim(data) == 2 and data.shape[1] == 9 and name.startswith("stress"):
        return "".join(f' ComponentName{k}="{c}"' for k, c in enumerate(TENSOR))
    return ""


def vtu_text(points, cells, cell_type: int, point_data: dict, cell_data: dict, field_data: dict):
    """A VTK XML UnstructuredGrid of one cell type, piece by piece (each DataArray compressed
    when its turn comes: `_write` streams them, so no more than one array's text is held)."""
    n, nc, nv = len(points), len(cells), cells.shape[1]
    yield ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" '
           'header_type="UInt64" compressor="vtkZLibDataCompressor">\n<UnstructuredGrid>\n<FieldData>\n')
    for k, v in field_data.items():
        yield _array(k, v, f' NumberOfTuples="{len(v)}"')
    yield f'</FieldData>\n<Piece NumberOfPoints="{n}" NumberOfCells="{nc}">\n<Points>\n'
    yield _array("Points", points)
    yield "</Points>\n<Cells>\n"
    yield _array("connectivity", cells.ravel())
    yield _array("offsets", nv * np.arange(1, nc + 1))
    yield _array("types", np.full(nc, cell_type), vtk_type="UInt8")
    yield "</Cells>\n<PointData>\n"
    for k, v in point_data.items():
        yield _array(k, v, _components(k, v))
    yield "</PointData>\n<CellData>\n"
    for k, v in cell_data.items():
        yield _array(k, v, _components(k, v))
    yield "</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n"


def vtm_text(blocks: list[tuple[str, str]]) -> str:
    """A VTK multiblock of (name, file relative to the .vtm) blocks."""
    items = "".join(f'<DataSet index="{i}" name={quoteattr(name)} file={quoteattr(file)}/>\n'
                    for i, (name, file) in enumerate(blocks))
    return ('<?xml version="1.0"?>\n<VTKFile type="vtkMultiBlockDataSet" version="1.0" byte_order="LittleEndian">\n'
            f"<vtkMultiBlockDataSet>\n{items}</vtkMultiBlockDataSet>\n</VTKFile>\n")


def _write(path: Path, text) -> None:
    """`text` (a str, or str pieces written as they come) to `path` whole or not at all
    (WriteError on an I/O fault)."""
    from .store import WriteError
    tmp = path.with_name(f".{path.name}.{os.getpid()}.part")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "w", encoding="ascii") as fh:
            fh.writelines([text] if isinstance(text, str) else text)
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise WriteError(f"cannot write {path}: {e.strerror or e}") from None
    except BaseException:       # a piece that failed to make (or a Ctrl-C) leaves no partial file
        tmp.unlink(missing_ok=True)
        raise


def write_paraview(ds: Data, path: str | Path, zone=None, facets: np.ndarray | None = None) -> Path:
    """OUT.vtm with OUT.vtu (the volume) and, with a contact `zone` and its slave `facets`,
    OUT-contact.vtu beside it (without: an OUT-contact.vtu of an earlier solve is removed, not
    left to be read as this one's); returns the .vtm."""
    from .store import WriteError
    vtm = Path(path).with_suffix(".vtm")
    surface = vtm.with_name(f"{vtm.stem}-contact.vtu")
    blocks = [("volume", vtm.with_suffix(".vtu"), volume(ds))]
    if zone is not None and "contact_pressure" in ds:
        blocks.append(("contact surface", surface, contact_surface(ds, zone, facets)))
    else:
        try:
            surface.unlink(missing_ok=True)
        except OSError as e:
            raise WriteError(f"cannot remove the stale {surface}: {e.strerror or e}") from None
    for _, file, parts in blocks:
        _write(file, vtu_text(*parts))
    _write(vtm, vtm_text([(name, file.name) for name, file, _ in blocks]))
    return vtm
