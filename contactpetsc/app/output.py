"""Field output: one HDF5 file per step, written in parallel, with an XDMF sidecar for ParaView.

Each rank writes its own rows of every field straight into the shared file
(h5py's MPI-IO driver under mpirun; Debian's h5py picks its MPI build when
the process runs under an MPI launcher).  Datasets are stored (ny, nx), row j
at y = j dy, so that the XDMF ``3DCoRectMesh`` (which lists the slowest axis
first) shows x horizontally.  Files are written to a temporary name and
renamed when complete: a reader never sees half a step, and an interrupted
run keeps every finished step.
"""
from __future__ import annotations

import json
import os

import h5py
import numpy as np
from mpi4py import MPI

from ..collective import collective_call
from ..stack import check_parallel_output

FIELDS = ("pressure", "gap", "displacement", "heights", "contact")
ADHESIVE_FIELDS = ("contact_pressure", "adhesive_pressure", "adhesive")
AXES = "y,x"   #: the axis order of every stored field (slowest first), a file and dataset attribute
UNITS = {"pressure": "Pa", "gap": "m", "displacement": "m", "heights": "m", "contact": "1",
         "contact_pressure": "Pa", "adhesive_pressure": "Pa", "adhesive": "1"}


def write_text_atomic(path: str, text: str) -> None:
    """Write ``text`` to a temporary name, flush it to disk, then rename: readers never see half a
    file, and a failed write (disk full, a kill) leaves the previous version in place."""
    tmp = path + ".tmp"
    try:
        with open(tmp, "w", newline="") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    os.replace(tmp, path)


def _write_h5(path: str, comm, fill) -> None:
    """Create the HDF5 file ``path`` and ``fill(file)`` it.

    On one rank the file is built in memory and written with Python's own I/O: HDF5 that
    fails to write (a full disk) and then closes its file crashes the process (SIGSEGV),
    where a failed Python write raises OSError.  On several ranks every rank writes its own
    rows through MPI-IO.
    """
    if comm.Get_size() > 1:
        check_parallel_output(comm.Get_size(), True)
        with h5py.File(path, "w", driver="mpio", comm=comm) as f:
            fill(f)
        return
    with h5py.File(path, "w", driver="core", backing_store=False) as f:
        fill(f)
        f.flush()
        image = f.id.get_file_image()
    with open(path, "wb") as f:
        f.write(image)
        f.flush()
        os.fsync(f.fileno())


def _room(directory: str) -> float:
    """Bytes one file in ``directory`` may still take: the free space, or less where the
    process's file-size limit (RLIMIT_FSIZE) is smaller."""
    import resource
    st = os.statvfs(directory)
    room = float(st.f_bavail * st.f_frsize)
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return room if limit == resource.RLIM_INFINITY else min(room, float(limit))


def _check_room(directory: str, final: str, comm, need: float) -> None:
    """Refuse, on every rank, a step file that does not fit before any rank starts writing it:
    a collective MPI-IO write that fails on one rank only leaves the others waiting."""
    room = comm.allreduce(collective_call(comm, OSError, f"cannot write {final}: {{error}}",
                                          _room, directory), op=MPI.MIN)
    if room < need:
        raise OSError(f"cannot write {final}: it needs about {need / 2**20:.2f} MiB, the output "
                      f"directory has room for {room / 2**20:.2f} MiB (free space or the file size "
                      f"limit); the steps written so far are kept: free some space and continue "
                      f"with --restart")


def write_state(directory: str, step: int, grid, heights, state, attrs: dict) -> str:
    """Write step ``step`` of ``state`` (a ContactState) to ``directory/step_NNNN.h5`` (+ ``.xdmf``).

    Collective over the grid's communicator.  Returns the HDF5 path.  A failed write (a
    full disk) raises OSError naming the file on every rank and leaves no temporary file.
    """
    comm = grid.mpi_comm
    name = f"step_{step:04d}.h5"
    final = os.path.join(directory, name)
    tmp = final + ".tmp"
    rows = {
        "pressure": grid.rows(state.pressure, readonly=True),
        "gap": grid.rows(state.gap, readonly=True),
        "displacement": grid.rows(state.displacement, readonly=True),
        "heights": grid.rows(heights, readonly=True),
    }
    rows["contact"] = (rows["pressure"] > 0).astype(np.float64)
    fields = FIELDS
    if hasattr(state, "adhesive_pressure"):
        # adhesive states: the two pressures stored apart (restart needs both) and the adhesive mask
        fields = FIELDS + ADHESIVE_FIELDS
        rows["contact_pressure"] = grid.rows(state.contact_pressure, readonly=True)
        rows["adhesive_pressure"] = grid.rows(state.adhesive_pressure, readonly=True)
        rows["adhesive"] = (rows["pressure"] < 0).astype(np.float64)

    def fill(f):
        for key, value in attrs.items():
            f.attrs[key] = value if isinstance(value, (int, float, str)) else json.dumps(value)
        for field in ("approach", "mean_pressure", "force", "contact_fraction",
                      "complementarity_error", "converged"):
            f.attrs[field] = getattr(state, field)
        f.attrs["dx"], f.attrs["dy"] = grid.dx, grid.dy
        f.attrs["axes"] = AXES
        for field in fields:
            dset = f.create_dataset(field, (grid.ny, grid.nx), dtype="f8")
            dset.attrs["unit"] = UNITS[field]
            dset.attrs["axes"] = AXES
            if comm.Get_size() > 1:
                with dset.collective:  # one MPI-IO write for all ranks
                    dset[grid.ys:grid.ye, :] = rows[field]
            else:
                dset[grid.ys:grid.ye, :] = rows[field]

    # the datasets, plus the attributes (the scene and versions) and HDF5's own structure
    _check_room(directory, final, comm, 8.0 * grid.nx * grid.ny * len(fields) + 2**16
                + sum(len(str(v)) for v in attrs.values()))
    try:
        _write_h5(tmp, comm, fill)
        error = None
    except Exception as exc:  # noqa: BLE001 - reported below, on every rank
        error = f"{type(exc).__name__}: {exc}"
    errors = [e for e in comm.allgather(error) if e]
    if errors:
        if comm.Get_rank() == 0 and os.path.exists(tmp):
            os.remove(tmp)
        comm.Barrier()
        raise OSError(f"cannot write {final}: {errors[0]}")

    def publish():
        if comm.Get_rank() == 0:
            os.replace(tmp, final)
            _write_xdmf(os.path.join(directory, f"step_{step:04d}.xdmf"), name, grid, fields)

    collective_call(comm, OSError, f"cannot write {final}: {{error}}", publish)
    return final


def _write_xdmf(path: str, h5name: str, grid, fields=FIELDS) -> None:
    # a 3-D mesh one node thick, axes listed slowest first (z, y, x; dz := dx): ParaView reads a
    # 2DCoRectMesh into its y-z plane, this one into the x-y plane; spacings in double precision
    dims = f"1 {grid.ny} {grid.nx}"
    attrs = "\n".join(
        f'      <Attribute Name="{field}" AttributeType="Scalar" Center="Node">\n'
        f'        <DataItem Dimensions="{dims}" NumberType="Float" Precision="8" Format="HDF">'
        f'{h5name}:/{field}</DataItem>\n      </Attribute>' for field in fields)
    text = f"""<?xml version="1.0" ?>
<Xdmf Version="3.0">
  <Domain>
    <Grid Name="surface" GridType="Uniform">
      <Topology TopologyType="3DCoRectMesh" Dimensions="{dims}"/>
      <Geometry GeometryType="ORIGIN_DXDYDZ">
        <DataItem Dimensions="3" NumberType="Float" Precision="8" Format="XML">0 0 0</DataItem>
        <DataItem Dimensions="3" NumberType="Float" Precision="8" Format="XML">{grid.dx!r} {grid.dy!r} {grid.dx!r}</DataItem>
      </Geometry>
{attrs}
    </Grid>
  </Domain>
</Xdmf>
"""
    write_text_atomic(path, text)
