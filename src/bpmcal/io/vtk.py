"""VTK XML PolyData (.vtp) export of particles and cracks, for ParaView.

Particles: points at the ball centres with point data ``radius`` [m], ``id``,
``displacement`` [m] and ``velocity`` [m/s] (final state), ``broken_bonds`` (cracks
touching the ball). In ParaView: *Glyph* with *Sphere* glyphs, scale by ``radius``
(scale factor 2 for diameter), or *Point Gaussian* with the radius array.

Cracks: one point per broken bond at the contact point with ``normal``, ``radius`` [m],
``mode`` (1 tension, 2 shear), ``step``, ``energy`` [J]. Render as discs: *Glyph* with a
*Cylinder* (or 2-D disc) source oriented by ``normal`` and scaled by ``radius``, colour by
``mode``. A ``.pvd`` collection groups the files.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .atomic import write_text
from .h5 import RunFileError, check_run_file, read_bonds, read_cracks, read_particles

#: the most balls (or cracks) a run's export may hold: the engine's specimens are refused
#: above 2 million balls (``lab.budget.MAX_BALLS``); a file declaring more is not a run
MAX_POINTS = 5_000_000


def _arr(name, a, ncomp=1):
    a = np.asarray(a)
    kind = "Float64" if a.dtype.kind == "f" else "Int64"
    body = " ".join(repr(float(x)) if kind == "Float64" else str(int(x)) for x in a.reshape(-1))
    return (f'<DataArray type="{kind}" Name="{name}" NumberOfComponents="{ncomp}" '
            f'format="ascii">{body}</DataArray>')


def write_vtp(path, points: np.ndarray, point_data: dict) -> Path:
    """Write points with point data as VTK XML PolyData (ASCII)."""
    path = Path(path)
    pts = np.asarray(points, float).reshape(-1, 3)
    n = pts.shape[0]
    arrays = []
    for k, v in point_data.items():
        v = np.asarray(v)
        ncomp = 1 if v.ndim == 1 else v.shape[1]
        arrays.append(_arr(k, v, ncomp))
    verts = " ".join(str(i) for i in range(n))
    offs = " ".join(str(i + 1) for i in range(n))
    xml = (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="PolyData" version="0.1" byte_order="LittleEndian">\n'
        '<PolyData>\n'
        f'<Piece NumberOfPoints="{n}" NumberOfVerts="{n}" NumberOfLines="0" '
        'NumberOfStrips="0" NumberOfPolys="0">\n'
        f'<Points>{_arr("Points", pts, 3)}</Points>\n'
        f'<PointData>{"".join(arrays)}</PointData>\n'
        f'<Verts><DataArray type="Int64" Name="connectivity" format="ascii">{verts}</DataArray>'
        f'<DataArray type="Int64" Name="offsets" format="ascii">{offs}</DataArray></Verts>\n'
        '</Piece>\n</PolyData>\n</VTKFile>\n')
    return write_text(path, xml)


def _check_shapes(path, ini: dict, fin: dict, bonds: dict, cr) -> int:
    """The ball count of a run's arrays, after checking that they fit together (a
    RunFileError naming the first that does not: a damaged or crafted file)."""
    def need(cond, what):
        if not cond:
            raise RunFileError(f"{path}: {what}; not a bpmcal run file that can be exported")

    need(not ini or {"position", "radius"} <= set(ini), "/particles/initial lacks position "
         "or radius")
    n = ini["position"].shape[0] if ini else 0
    need(n <= MAX_POINTS, f"{n:,} balls, more than {MAX_POINTS:,}")
    if ini:
        need(ini["position"].shape == (n, 3) and ini["radius"].shape == (n,),
             "/particles/initial: position is not (n, 3) or radius not (n,)")
    if fin and ini:
        need(all(k in fin and fin[k].shape == (n, 3) for k in ("position", "velocity")),
             "/particles/final: position or velocity is not (n, 3) for the n initial balls")
    if bonds and n:
        need({"i", "j", "state"} <= set(bonds), "/bonds lacks i, j or state")
        m = bonds["state"].shape
        need(len(m) == 1 and bonds["i"].shape == m and bonds["j"].shape == m,
             "/bonds: i, j and state differ in shape")
        for k in ("i", "j"):
            need(bonds[k].dtype.kind in "iu" and (bonds[k].size == 0 or (
                bonds[k].min() >= 0 and bonds[k].max() < n)), f"/bonds/{k}: not ball indices")
    if len(cr):
        cols = {"x", "y", "z", "normal_x", "normal_y", "normal_z", "radius", "mode", "step",
                "energy"}
        need(cols <= set(cr.columns), "/cracks lacks " + ", ".join(sorted(cols - set(cr.columns))))
        need(len(cr) <= MAX_POINTS, f"{len(cr):,} cracks, more than {MAX_POINTS:,}")
    return n


def export_run(h5path, outdir) -> list[Path]:
    """particles_initial.vtp, particles_final.vtp, cracks.vtp and run.pvd for one run
    (a RunFileError, before anything is written, if ``h5path`` is not a bpmcal run file
    or its arrays do not fit together)."""
    h5path = Path(h5path)
    check_run_file(h5path)
    out = Path(outdir)
    files = []
    ini = read_particles(h5path, "initial")
    fin = read_particles(h5path, "final")
    bonds = read_bonds(h5path)
    cr = read_cracks(h5path)
    n = _check_shapes(h5path, ini, fin, bonds, cr)
    broken = np.zeros(n, np.int64)
    if bonds and n:
        st = np.isin(bonds["state"], (1, 2))  # broken (3: a flat joint never bonded)
        np.add.at(broken, bonds["i"][st], 1)
        np.add.at(broken, bonds["j"][st], 1)
    if ini:
        files.append(write_vtp(out / "particles_initial.vtp", ini["position"],
                               {"radius": ini["radius"], "id": np.arange(n)}))
    if fin and ini:
        files.append(write_vtp(out / "particles_final.vtp", fin["position"], {
            "radius": ini["radius"], "id": np.arange(n),
            "displacement": fin["position"] - ini["position"],
            "velocity": fin["velocity"], "broken_bonds": broken}))
    if len(cr):
        pts = cr[["x", "y", "z"]].to_numpy()
        nrm = cr[["normal_x", "normal_y", "normal_z"]].to_numpy()
        files.append(write_vtp(out / "cracks.vtp", pts, {
            "normal": nrm, "radius": cr["radius"].to_numpy(), "mode": cr["mode"].to_numpy(),
            "step": cr["step"].to_numpy(), "energy": cr["energy"].to_numpy(),
            **{k: cr[k].to_numpy() for k in ("element", "area") if k in cr}}))
    else:
        files.append(write_vtp(out / "cracks.vtp", np.zeros((0, 3)), {}))
    pvd = out / "run.pvd"
    items = "\n".join(f'<DataSet part="{i}" file="{f.name}"/>' for i, f in enumerate(files))
    write_text(pvd, '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
               f'<Collection>\n{items}\n</Collection>\n</VTKFile>\n')
    return files + [pvd]
