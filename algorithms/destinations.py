"""No output over an input: the rules a step's outputs obey, checked before any work.

A step names its inputs, every file and folder it reads (`Input`: its file and layer parameters and what
they lead to: `files_of` a dataset, `Block.files` of a block: its journals, point folders, images and their
orientation files), and its destinations (`Destination`: every file or folder it writes, with the
extensions its writer honours). `check` refuses, with an error that names both parameters, before anything
is computed or written, where

- a destination is an input: the same file by its real path (symbolic links resolved) or by its identity on
  disk (device and inode: a hard link);
- a destination lies inside an input folder (a block's point folder, which the block's next store removes
  as a whole), or a folder the step replaces as a whole (FOLDER) holds an input;
- two destinations are the same file, or one lies inside a folder the step replaces as a whole;
- a folder the step replaces as a whole holds something, but not the mark of a folder the step made (a
  simulated scene's truth file): a folder of the user's own files is never replaced;
- a destination's name ends in an extension its writer does not honour (CSV text named .shp or .xlsx);
- a destination exists and is not what its writer replaces: a device node (/dev/full), a FIFO, a socket or
  a folder where a file is written, a file where a folder is written (atomic.refuse_non_file);
- a destination's folder cannot be written (atomic.check_destination).

A destination's companions (a shapefile's .shx, .dbf, .prj: atomic.companions) count as destinations.
What is not refused: a destination folder that files are written into (INTO) may hold inputs, and a file
destination may lie beside inputs; only the files written count.
"""

import contextlib
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NoReturn

from . import atomic
from .errors import InputError, MetadataError
from .file_identity import FileIdentity
from .sensors import orientation_source

#: destination kinds: a file written (replacing a file of that name), a folder replaced as a whole, a folder
#: that files are written into
FILE, FOLDER, INTO = "file", "folder", "into"
#: the extensions of every raster a step writes (all are GeoTIFF)
RASTER_EXTENSIONS = ("tif", "tiff")


@dataclass(frozen=True)
class Input:
    """A file or folder a step reads; `label` names its parameter in messages ("BLOCK (Block)"), `part` what
    the file is to it where it is not the file the parameter names ("the image HRG", "a point folder")."""

    path: str
    label: str
    part: str = ""


@dataclass(frozen=True)
class Destination:
    """A file or folder a step writes: `kind` FILE, FOLDER or INTO (module docstring); `extensions` the
    extensions its writer honours (lower case, without the dot; empty: any); `mark` of a FOLDER, the file
    (relative to it) that marks a folder the step made; `label` names it in messages."""

    path: str
    label: str
    kind: str = FILE
    extensions: tuple = ()
    mark: str = ""


def files_of(path) -> list:
    """The files a dataset at `path` consists of: itself, what GDAL reads with it (an image's .aux.xml and
    _RPC.TXT, a DIMAP product's METADATA.DIM and raster) and the orientation file a sensor model is read from
    (sensors.orientation_source)."""
    path = os.fspath(path)
    found = [path]
    if not os.path.isfile(path):
        return found
    from osgeo import gdal

    gdal.PushErrorHandler("CPLQuietErrorHandler")
    try:
        ds = gdal.OpenEx(path, gdal.OF_READONLY)
        found += (ds.GetFileList() or []) if ds is not None else []
    except RuntimeError:  # no format GDAL knows (a LAS file, a CSV of another layout)
        pass
    finally:
        ds = None
        gdal.PopErrorHandler()
    with contextlib.suppress(MetadataError, OSError):
        found.append(orientation_source(path))
    return list(dict.fromkeys(found))


def _destination_files(destination: Destination) -> list:
    """The files a FILE destination writes: its path and its companions."""
    return [destination.path, *atomic.companions(destination.path)]


def _how(given: str, other: str, a: FileIdentity, b: FileIdentity) -> str:
    """How the paths `given` and `other`, found the same (FileIdentity a, b), are the same file, for a message."""
    if os.path.abspath(given) == os.path.abspath(other):
        return f"both name {given}"
    if a.real == b.real:
        return f"{given} leads to {other} through a symbolic link"
    return f"{given} is a hard link of {other} (the same file)"


def _refuse(text: str) -> NoReturn:
    raise InputError(f"{text}; nothing was written")


def _check_inputs(destination: Destination, inputs: Sequence[Input]) -> None:
    """Refuse `destination` where it would overwrite or remove one of `inputs` (module docstring)."""
    paths = [destination.path] if destination.kind != FILE else _destination_files(destination)
    for path in paths:
        target = FileIdentity.of(path)
        for item in inputs:
            source = FileIdentity.of(item.path)
            name = f"{item.label}, {item.part}" if item.part else item.label
            if target.same(source):
                _refuse(
                    f"the output {destination.label} would overwrite the input {name}: "
                    f"{_how(path, item.path, target, source)}. Choose another output path"
                )
            if os.path.isdir(source.real) and target.inside(source):
                _refuse(
                    f"the output {destination.label} {path} lies inside the input {name} {item.path}, a "
                    "folder replaced or removed as a whole. Choose a path outside it"
                )
            if destination.kind == FOLDER and source.inside(target):
                _refuse(
                    f"the output folder {destination.label} {path} is replaced as a whole, and it holds the "
                    f"input {name} {item.path}. Choose another folder"
                )


def _check_each_other(destinations: list) -> None:
    """Refuse two destinations that are the same file, or one inside a folder replaced as a whole."""
    for k, a in enumerate(destinations):
        for b in destinations[k + 1 :]:
            for pa in [a.path] if a.kind != FILE else _destination_files(a):
                for pb in [b.path] if b.kind != FILE else _destination_files(b):
                    ia, ib = FileIdentity.of(pa), FileIdentity.of(pb)
                    if ia.same(ib):
                        _refuse(
                            f"the outputs {a.label} and {b.label} are the same file: {_how(pa, pb, ia, ib)}. "
                            "Give each its own path"
                        )
                    for outer, inner, i_outer, i_inner in ((a, b, ia, ib), (b, a, ib, ia)):
                        if outer.kind == FOLDER and i_inner.inside(i_outer):
                            _refuse(
                                f"the output {inner.label} {inner.path} lies inside the output folder "
                                f"{outer.label} {outer.path}, which is replaced as a whole. Choose a path "
                                "outside it"
                            )


def _check_extension(destination: Destination) -> None:
    """Refuse a FILE destination whose extension its writer does not honour."""
    if destination.kind != FILE or not destination.extensions:
        return
    ext = os.path.splitext(destination.path)[1].lower().lstrip(".")
    if ext not in destination.extensions:
        *others, last = [f".{e}" for e in destination.extensions]
        names = f"{', '.join(others)} or {last}" if others else last
        given = f"ends in '.{ext}'" if ext else "has no extension"
        _refuse(
            f"the output {destination.label} {destination.path} is written as {names} only, and its name {given}: "
            f"a file is never written in one format under another's name. Give a name ending in {names}"
        )


def _check_kind(destination: Destination) -> None:
    """Refuse a destination where something its writer never replaces is in the way (atomic.refuse_non_file):
    a device, a FIFO, a socket or a folder where a file is written, anything but a folder where one is."""
    what = f"the output {destination.label}"
    if destination.kind == FILE:
        for file in _destination_files(destination):
            atomic.refuse_non_file(file, what)
    elif not os.path.isdir(destination.path):
        atomic.refuse_non_folder(destination.path, f"the output folder {destination.label}")
    elif (
        destination.kind == FOLDER
        and os.listdir(destination.path)
        and not os.path.isfile(os.path.join(destination.path, destination.mark))
    ):
        _refuse(
            f"the output folder {destination.label} {destination.path} is replaced as a whole, and it holds "
            f"files this step did not make (it has no {destination.mark}). Give a new or empty folder, or one "
            "this step made"
        )


def _check_writable(destination: Destination) -> None:
    """That the destination's folder can be written (atomic.check_destination)."""
    what = f"the output {destination.label}"
    path = destination.path
    if destination.kind == FILE:
        atomic.check_destination(path, what)  # its companions lie in its folder (_check_kind saw them)
    elif destination.kind == INTO and os.path.isdir(path):
        atomic.check_destination(os.path.join(path, "probe"), f"into {what}")  # written into
    else:
        atomic.check_destination(path.rstrip(os.sep) + ".probe", what)  # made in its parent folder


def check(inputs: Sequence[Input], destinations: Sequence[Destination]) -> None:
    """Refuse (InputError, StorageError) the `destinations` of a step that reads `inputs`, where one would
    damage an input, another destination or something that is not a file, or cannot be written as named
    (module docstring). Reads the file system's metadata and probes the folders: none of the step's work."""
    destinations = list(destinations)
    for destination in destinations:
        _check_inputs(destination, inputs)
    _check_each_other(destinations)
    for check_one in (_check_kind, _check_extension, _check_writable):
        for destination in destinations:
            check_one(destination)
