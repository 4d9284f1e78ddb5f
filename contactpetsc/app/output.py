"""Field output: one HDF5 file per step, written in parallel, with an XDMF sidecar for ParaView.

Each rank writes its own rows of every field straight into the shared file
(h5py's MPI-IO driver under mpirun; Debian's h5py picks its MPI build when
the process runs under an MPI launcher).  Datasets are stored (ny, nx), row j
at y = j dy, so that the XDMF ``3DCoRectMesh`` (which lists the slowest axis
first) shows x horizontally.  Files are written to a temporary name and
renamed when complete: a reader never sees half a step, and an interrupted
run keeps every finished step.  Masks are uint8, the other fields float64 or
(``output.field_precision``) float32, except what a restart or a height
reader needs (``RESTART_FIELDS``, heights), always float64.  ``fields.xdmf``
collects the written steps in one temporal collection.
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
MASKS = ("contact", "adhesive")            #: 0/1 fields, stored as uint8
#: the fields a restart resumes from (the stepper's state), without and with adhesion: written
#: in every step file at full precision, whatever output.fields and output.field_precision say
RESTART_FIELDS = {False: ("pressure",), True: ("contact_pressure", "adhesive_pressure")}
#: read back as a surface (geometry.kind = "file"): always float64
FULL_PRECISION = ("heights",)
#: output.length_unit: the factor from metres that the XDMF files apply to lengths (the
#: geometry, the approach as time, and the length fields); the HDF5 data stay in metres
LENGTH_UNITS = {"m": 1.0, "um": 1e6, "nm": 1e9}
COLLECTION = "fields.xdmf"   #: the temporal collection of every written step
#: the group of the nested iteration's coarse levels in an adhesive sweep's step files of older
#: versions (the levels now follow the fine state; a restart reads the step's own fields only)
COARSE_LEVELS = "coarse_levels"
_XDMF_TYPES = {"f8": ("Float", 8), "f4": ("Float", 4), "u1": ("UChar", 1)}


def available_fields(adhesive: bool) -> tuple:
    """The field names a scene's step files can hold (``output.fields``)."""
    return FIELDS + (ADHESIVE_FIELDS if adhesive else ())


def field_types(selected, adhesive: bool, precision: str = "float64") -> dict:
    """{field: HDF5 type code} of a step file: the ``selected`` fields (True: all) and the
    restart fields, in the order of ``available_fields``; masks uint8 ("u1"), the restart
    fields and heights float64 ("f8"), the others ``precision`` ("f8" or "f4")."""
    names = available_fields(adhesive)
    chosen = set(names if selected is True else selected) | set(RESTART_FIELDS[adhesive])
    low = "f4" if precision == "float32" else "f8"
    return {name: "u1" if name in MASKS else
            "f8" if name in FULL_PRECISION or name in RESTART_FIELDS[adhesive] else low
            for name in names if name in chosen}


def scene_field_types(scene: dict) -> dict:
    """``field_types`` of a validated scene (empty with output.fields = false)."""
    from .scenes import adhesive
    out = scene["output"]
    if out["fields"] is False:
        return {}
    return field_types(out["fields"], adhesive(scene), out["field_precision"])


def expected_step_files(scene: dict) -> int:
    """The step files a path writes at least: every ``field_every``-th step and the last (jumps,
    unconverged steps and pull-off candidates come on top); 0 without fields."""
    if scene["output"]["fields"] is False:
        return 0
    steps = len(scene["protocol"]["values"])
    every = scene["output"]["field_every"]
    return steps // every + (steps % every != 0)


def step_file_bytes(types: dict, nodes: int, attrs: int = 0) -> float:
    """Bytes of one step file: the datasets, plus the attributes (the scene and versions,
    ``attrs`` characters) and HDF5's own structure."""
    return nodes * sum(np.dtype(t).itemsize for t in types.values()) + 2**16 + attrs


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


def write_state(directory: str, step: int, grid, heights, state, attrs: dict, *, types: dict | None = None,
                length_unit: str = "m") -> str:
    """Write step ``step`` of ``state`` (a ContactState) to ``directory/step_NNNN.h5`` (+ ``.xdmf``).

    ``types``: {field: HDF5 type code} (``field_types``; default: every field of the state,
    masks uint8, the rest float64).  Collective over the
    grid's communicator.  Returns the HDF5 path.  A failed write (a full disk) raises OSError
    naming the file on every rank and leaves no temporary file.
    """
    comm = grid.mpi_comm
    if types is None:
        types = field_types(True, hasattr(state, "adhesive_pressure"))
    name = f"step_{step:04d}.h5"
    final = os.path.join(directory, name)
    tmp = final + ".tmp"
    sources = {"pressure": state.pressure, "gap": state.gap, "displacement": state.displacement,
               "heights": heights}
    if hasattr(state, "adhesive_pressure"):
        # adhesive states: the two pressures stored apart (restart needs both)
        sources.update(contact_pressure=state.contact_pressure, adhesive_pressure=state.adhesive_pressure)
    rows = {field: grid.rows(vec, readonly=True) for field, vec in sources.items()}
    rows["contact"] = rows["pressure"] > 0
    rows["adhesive"] = rows["pressure"] < 0

    def fill(f):
        for key, value in attrs.items():
            f.attrs[key] = value if isinstance(value, (int, float, str)) else json.dumps(value)
        for field in ("approach", "mean_pressure", "force", "contact_fraction",
                      "complementarity_error", "converged"):
            f.attrs[field] = getattr(state, field)
        f.attrs["dx"], f.attrs["dy"] = grid.dx, grid.dy
        f.attrs["axes"] = AXES
        for field, code in types.items():
            dset = _write_rows(f, field, grid, rows[field], code)
            if field in ("heights", "gap"):   # gaps (h, and g = h + v - delta): so read back as a height file
                dset.attrs["heights_are"] = "gap"

    need = step_file_bytes(types, grid.nx * grid.ny, sum(len(str(v)) for v in attrs.values()))
    _check_room(directory, final, comm, need)
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
            write_text_atomic(os.path.join(directory, f"step_{step:04d}.xdmf"),
                              _xdmf([_grid_xml(name, grid, types, length_unit)]))

    collective_call(comm, OSError, f"cannot write {final}: {{error}}", publish)
    return final


def _write_rows(group, field: str, grid, data, code: str):
    """A (ny, nx) dataset ``field`` of type ``code`` in ``group``, each rank writing its rows
    ``data`` (float32 by rounding to nearest, numpy's cast; masks 0/1; float64 as it is)."""
    dset = group.create_dataset(field, (grid.ny, grid.nx), dtype=code)
    dset.attrs["unit"] = UNITS[field]
    dset.attrs["axes"] = AXES
    data = np.asarray(data, dtype=code)
    if grid.mpi_comm.Get_size() > 1:
        with dset.collective:  # one MPI-IO write for all ranks
            dset[grid.ys:grid.ye, :] = data
    else:
        dset[grid.ys:grid.ye, :] = data
    return dset


def check_step_file(path: str, grid, fields: tuple) -> None:
    """A step file fit to restart from: complete, ``fields`` present, every dataset of the grid's
    (ny, nx) shape and axes "y,x"."""
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path} is missing")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise ValueError(f"{path} is damaged ({exc})") from None
    with f:
        axes = f.attrs.get("axes", AXES)
        if axes != AXES:
            raise ValueError(f"{path} has axes {axes!r}; this version reads {AXES!r}")
        for name in fields:
            if name not in f:
                raise ValueError(f"{path} has no dataset {name!r}")
        datasets = [name for name in f if name != COARSE_LEVELS]   # the coarse grids: ``coarse_levels``
        for name in datasets:
            if f[name].shape != (grid.ny, grid.nx):
                raise ValueError(f"{path}: {name} has shape {f[name].shape}: it does not fit the scene's grid "
                                 f"(ny, nx) = ({grid.ny}, {grid.nx})")
            if f[name].attrs.get("axes", AXES) != AXES:
                raise ValueError(f"{path}: {name} has axes {f[name].attrs['axes']!r}; expected {AXES!r}")
        sizes = []   # every dataset's, an older file's coarse levels' too
        f.visititems(lambda _, obj: sizes.append(obj.size * obj.dtype.itemsize)
                     if isinstance(obj, h5py.Dataset) else None)
        need = sum(sizes)
    if os.path.getsize(path) < need:
        raise ValueError(f"{path} is truncated ({os.path.getsize(path)} bytes, its datasets need {need})")


def write_collection(directory: str, grid, steps: list, length_unit: str = "m") -> None:
    """``directory/fields.xdmf`` (rank 0; written whole under a temporary name): one temporal
    collection of the written ``steps``, a list of (step, approach [m], {field: type code}).

    The time of each step is its approach in ``length_unit`` when the approaches of the listed
    steps strictly increase (loading paths, load control), else the step number (paths that
    unload or turn: ParaView orders steps by time and merges equal times); the XDMF file
    names which in an Information item ``time``.
    """
    scale = LENGTH_UNITS[length_unit]
    approaches = [a for _, a, _ in steps]
    by_approach = all(b > a for a, b in zip(approaches, approaches[1:]))
    grids = []
    for step, approach, types in steps:
        time = approach * scale if by_approach else float(step)
        grids.append(_grid_xml(f"step_{step:04d}.h5", grid, types, length_unit, time=time,
                               name=f"step_{step:04d}", indent=6))
    what = f"approach [{length_unit}]" if by_approach else "step"
    text = (f'    <Grid Name="steps" GridType="Collection" CollectionType="Temporal">\n'
            f'      <Information Name="time" Value="{what}"/>\n' + "".join(grids) + "    </Grid>\n")
    write_text_atomic(os.path.join(directory, COLLECTION), _xdmf([text]))


def read_written_step(path: str) -> tuple:
    """(approach [m], {field: type code}) of a step file, for the collection of a restarted run."""
    with h5py.File(path, "r") as f:
        return float(f.attrs["approach"]), {name: f[name].dtype.str[1:] for name in f
                                            if name != COARSE_LEVELS}


def _xdmf(grids: list) -> str:
    return ('<?xml version="1.0" ?>\n<Xdmf Version="3.0">\n  <Domain>\n' + "".join(grids)
            + "  </Domain>\n</Xdmf>\n")


def _grid_xml(h5name: str, grid, types: dict, length_unit: str, *, time: float | None = None,
              name: str = "surface", indent: int = 4) -> str:
    """One uniform grid of a step file's fields: a 3-D mesh one node thick, axes listed slowest
    first (z, y, x; dz := dx): ParaView reads a 2DCoRectMesh into its y-z plane, this one into the
    x-y plane; spacings in double precision.  Lengths (the spacing, the length fields) are shown
    in ``length_unit`` through an XDMF Function item, the data staying in metres."""
    scale = LENGTH_UNITS[length_unit]
    dims = f"1 {grid.ny} {grid.nx}"
    pad = " " * indent
    lines = [f'{pad}<Grid Name="{name}" GridType="Uniform">']
    if time is not None:
        lines.append(f'{pad}  <Time Value="{time!r}"/>')
    dx, dy = grid.dx * scale, grid.dy * scale
    lines += [f'{pad}  <Topology TopologyType="3DCoRectMesh" Dimensions="{dims}"/>',
              f'{pad}  <Geometry GeometryType="ORIGIN_DXDYDZ">',
              f'{pad}    <DataItem Dimensions="3" NumberType="Float" Precision="8" Format="XML">0 0 0</DataItem>',
              f'{pad}    <DataItem Dimensions="3" NumberType="Float" Precision="8" Format="XML">{dx!r} {dy!r} {dx!r}</DataItem>',
              f'{pad}  </Geometry>']
    for field, code in types.items():
        number, precision = _XDMF_TYPES[code]
        item = (f'<DataItem Dimensions="{dims}" NumberType="{number}" Precision="{precision}" '
                f'Format="HDF">{h5name}:/{field}</DataItem>')
        lines.append(f'{pad}  <Attribute Name="{field}" AttributeType="Scalar" Center="Node">')
        if UNITS[field] == "m" and scale != 1.0:
            lines += [f'{pad}    <DataItem ItemType="Function" Function="{scale!r}*$0" Dimensions="{dims}">',
                      f'{pad}      {item}', f'{pad}    </DataItem>']
        else:
            lines.append(f'{pad}    {item}')
        lines.append(f'{pad}  </Attribute>')
    lines.append(f'{pad}</Grid>')
    return "\n".join(lines) + "\n"
