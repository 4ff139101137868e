"""ParaView files of `wcs solve` and `wcs solve --worst` (`wcs.results.paraview`): a .vtm multiblock of
the volume (.vtu: displacement, the stress tensor, von Mises, named bodies and regions, units in
the names) and the contact surface (-contact.vtu: the results file's contact fields on the slave
facets), read back with meshio and compared with the results file."""
import base64
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import meshio
import numpy as np
import pytest
import xarray as xr

from wcs.cli import main

ROOT = Path(__file__).resolve().parents[2]
VALIDATION = ROOT / "studies" / "validation"
TENSOR = ("XX", "XY", "XZ", "YX", "YY", "YZ", "ZX", "ZY", "ZZ")       # VTK's 9-component tensor, row by row


def blocks(vtm: Path) -> dict[str, meshio.Mesh]:
    """The multiblock's datasets by name, each read with meshio."""
    root = ET.parse(vtm).getroot()
    assert root.get("type") == "vtkMultiBlockDataSet"
    return {d.get("name"): meshio.read(vtm.parent / d.get("file")) for d in root.iter("DataSet")}


def check(out: Path, ds: xr.Dataset, bodies: list[str]) -> dict[str, meshio.Mesh]:
    """The .vtm beside `out` holds the results file `ds`: everything compared exactly (the same
    float64 numbers, written in binary)."""
    b = blocks(out.with_suffix(".vtm"))
    assert set(b) == {"volume", "contact surface"}
    vol, surf = b["volume"], b["contact surface"]
    d = ds.sizes["dim"]
    assert np.array_equal(vol.points[:, :d], ds["coords"].values)
    assert np.array_equal(vol.point_data["displacement [m]"][:, :d], ds["displacement"].values)
    stress = vol.cell_data["stress [Pa]"][0].reshape(-1, 3, 3)              # ParaView's 9-component tensor
    assert stress.shape == (ds.sizes["cell"], 3, 3) and np.array_equal(stress, stress.transpose(0, 2, 1))
    for k, c in enumerate(ds["component"].values):
        i, j = "xyz".index(c[0]), "xyz".index(c[1])
        assert np.array_equal(stress[:, i, j], ds["stress"].values[:, k]), c
    text = out.with_suffix(".vtu").read_text()
    assert all(f'ComponentName{k}="{c}"' in text for k, c in enumerate(TENSOR))
    assert np.array_equal(vol.cell_data["von Mises stress [Pa]"][0], ds["von_mises"].values)
    assert np.array_equal(vol.cell_data["body"][0], ds["cell_body"].values)
    names = {k: int(v[0]) for k, v in vol.field_data.items()}
    assert {k: v for k, v in names.items() if k.startswith("body: ")} == {f"body: {n}": i for i, n in enumerate(bodies)}
    assert {f"region: {r}" for r in ds["region"].values} <= set(names)
    # the contact surface: the results file's contact nodes and fields, point by point
    assert np.array_equal(surf.points[:, :d], ds["contact_coords"].values)
    assert np.array_equal(surf.point_data["contact pressure [Pa]"], ds["contact_pressure"].values)
    assert np.array_equal(surf.point_data["gap [m]"], ds["contact_gap"].values)
    for name, var in (("slip", "contact_slip"), ("shear traction", "contact_shear")):
        unit = "m" if name == "slip" else "Pa"
        along = surf.point_data[f"{name} along tangents [{unit}]"]
        assert np.array_equal(along.reshape(ds[var].shape), ds[var].values)
        vector = surf.point_data[f"{name} [{unit}]"]                       # Σ c_k t_k: its tangential parts
        t = ds["contact_tangents"].values if "contact_tangents" in ds else None
        if t is not None:
            np.testing.assert_allclose(np.einsum("md,mkd->mk", vector, t), ds[var].values,
                                       rtol=0, atol=1e-14 * np.abs(ds[var].values).max())
        else:
            np.testing.assert_allclose(np.linalg.norm(vector, axis=1), np.abs(ds[var].values),
                                       rtol=1e-14, atol=0)
    assert (surf.point_data["contact pressure [Pa]"] > 0).any()             # a loaded contact, not zeros
    assert list(surf.field_data) == [f"contact: {n}" for n in np.unique(ds["contact_pair"].values)]
    cell = "line" if d == 2 else "triangle"
    assert surf.cells[0].type == cell and surf.cells[0].data.max() < ds.sizes["contact_node"]
    return b


def test_solve_writes_a_multiblock_with_the_contact_surface_2d(tmp_path, capsys):
    out = tmp_path / "pad.nc"
    assert main(["solve", str(VALIDATION / "tresca-pad.yaml"), "-o", str(out)]) == 0
    assert f"wrote {out} and {out.with_suffix('.vtm')}" in capsys.readouterr().out
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        b = check(out, ds, ["base", "pad"])
    seg = b["contact surface"].cells[0].data                                 # a polyline along the pad
    assert len(seg) == b["contact surface"].points.shape[0] - 1


def test_solve_writes_a_multiblock_with_the_contact_surface_3d(tmp_path):
    out = tmp_path / "blocks.nc"
    assert main(["solve", str(VALIDATION / "block-on-block-3d.yaml"), "-o", str(out), "--quiet"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        b = check(out, ds, ["base", "block"])
    assert b["volume"].cells[0].type == "tetra"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("worst")
    out = d / "run.nc"
    assert main(["run", str(VALIDATION / "stacked-layers.yaml"), "-o", str(out), "--quiet", "--no-mesh-check"]) == 0
    return out


def test_solve_worst_writes_the_same_for_a_worst_case(run, tmp_path):
    """The worst case of `pressure` solved again: its ParaView files hold the run's worst fields
    of that criterion (the run re-solves its worst cases: the same numbers)."""
    out = tmp_path / "worst.nc"
    assert main(["solve", str(VALIDATION / "stacked-layers.yaml"), "--worst", str(run), "pressure",
                 "-o", str(out), "--quiet"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        b = check(out, ds, ["base", "block"])
    with xr.open_dataset(run, engine="h5netcdf") as r:
        worst = r["worst_contact_pressure"].sel(criterion="pressure").values
    np.testing.assert_allclose(b["contact surface"].point_data["contact pressure [Pa]"], worst,
                               rtol=1e-12, atol=1e-12 * np.abs(worst).max())


@pytest.mark.slow
def test_the_3d_tunnels_contact_pressure_is_on_its_contact_surface(tmp_path):
    """The shipped 3D tunnel (about 10 s): its fault's pressure, gaps
    (round-off of -1e-13 m where closed), slips and shear tractions on the slave facets, equal to
    the results file's."""
    out = tmp_path / "tunnel.nc"
    assert main(["solve", str(ROOT / "studies" / "tunnel-fault-3d.yaml"), "-o", str(out), "--quiet"]) == 0
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        b = check(out, ds, ["hanging", "footwall"])
    assert b["contact surface"].cells[0].data.shape[1] == 3


def test_a_solve_without_contact_has_the_volume_only_and_no_stale_surface(tmp_path):
    """heated-plate has no contact: the .vtm holds the volume (with its temperature), and an
    OUT-contact.vtu left by an earlier solve to the same name is gone, not read as this one's."""
    out = tmp_path / "plate.nc"
    stale = tmp_path / "plate-contact.vtu"
    stale.write_text("an earlier solve's contact surface")
    assert main(["solve", str(ROOT / "studies" / "heated-plate.yaml"), "-o", str(out), "--quiet"]) == 0
    b = blocks(out.with_suffix(".vtm"))
    assert list(b) == ["volume"] and not stale.exists()
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        assert np.array_equal(b["volume"].point_data["temperature [K]"], ds["temperature"].values)


def test_blocks_are_compressed_at_zlibs_fastest_level():
    """A DataArray's zlib blocks carry FLEVEL 0 (RFC 1950: the fastest level, 3.5x faster to write
    than the default on a 3D solve's fields) and decompress to the array's bytes."""
    from wcs.results.paraview import BLOCK, _compressed
    raw = np.sin(np.arange(3 * BLOCK // 8 + 17, dtype=np.float64)).tobytes()
    text = _compressed(raw)
    head = 4 * ((8 * 7 + 2) // 3)                       # base64 of the header's 7 UInt64 (4 blocks)
    counts = np.frombuffer(base64.b64decode(text[:head]), dtype="<u8")
    assert list(counts[:3]) == [4, BLOCK, len(raw) - 3 * BLOCK]
    data = base64.b64decode(text[head:])
    ends = np.cumsum(counts[3:])
    parts = [data[a:b] for a, b in zip(np.r_[0, ends[:-1]], ends)]
    assert [p[1] >> 6 for p in parts] == [0] * 4
    assert b"".join(map(zlib.decompress, parts)) == raw


@pytest.mark.parametrize("text", ["body: rock", "a & b < c > d", "say \"hi\"", "it's", "both \" and '",
                                  "tab\there\nnew line\rreturn", "", "&amp; already"])
def test_attribute_quoting_is_the_standard_librarys(text):
    """The names written into the .vtu/.vtm quote as xml.sax.saxutils.quoteattr quotes them (the
    files stay byte for byte what they were); the escaped text parses back to the name."""
    from xml.sax.saxutils import quoteattr as standard
    from wcs.results.paraview import quoteattr
    assert quoteattr(text) == standard(text)
    assert ET.fromstring(f"<a n={quoteattr(text)}/>").get("n") == text


def test_a_vtu_whose_piece_fails_leaves_no_file(tmp_path):
    """The .vtu is written piece by piece (`vtu_text`: each array compressed when written); a
    piece that fails to make leaves neither a partial file nor the temporary one."""
    from wcs.results.paraview import _write

    def pieces():
        yield "<VTKFile>"
        raise ValueError("a field that cannot be written")

    path = tmp_path / "out.vtu"
    with pytest.raises(ValueError):
        _write(path, pieces())
    assert list(tmp_path.iterdir()) == []
    _write(path, iter(["<a>", "</a>"]))
    assert path.read_text() == "<a></a>" and [p.name for p in tmp_path.iterdir()] == ["out.vtu"]
