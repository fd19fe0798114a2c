"""A 2-D array in a `.npy` file, read and written by slices: the store of a grid too large to hold
in memory (the simulator's ground grids, a stored DEM).

The file is opened as a memory map only for the one slice read or written, then closed, so pages of
the grid do not stay mapped into the process between slices. It is allocated in full when it is made,
so a full disk is a StorageError then, not a fault (SIGBUS) when a page of a sparse file is first
written through the map."""

import os

import numpy as np

from .atomic import storage_error


class DiskArray:
    """A 2-D array in a .npy file with numpy slicing: a[key] reads (a copy), a[key] = v writes. `what`
    names the data in a StorageError."""

    def __init__(self, path, shape, dtype, what="the work files"):
        self.path, self.shape, self.dtype, self.what = path, tuple(shape), np.dtype(dtype), what
        try:
            np.lib.format.open_memmap(path, mode="w+", dtype=self.dtype, shape=self.shape).flush()
            with open(path, "r+b") as f:
                os.posix_fallocate(f.fileno(), 0, os.fstat(f.fileno()).st_size)
        except OSError as exc:
            raise storage_error(exc, path, what) from None

    @classmethod
    def existing(cls, path):
        """The DiskArray of the .npy file `path` as it is."""
        array = cls.__new__(cls)
        data = np.load(path, mmap_mode="r")
        array.path, array.shape, array.dtype, array.what = path, data.shape, data.dtype, "the work files"
        del data
        return array

    def _map(self, mode):
        return np.load(self.path, mmap_mode=mode)

    def __getitem__(self, key):
        data = self._map("r")
        out = np.array(data[key])
        del data
        return out

    def __setitem__(self, key, value):
        data = self._map("r+")
        try:
            data[key] = value
            data.flush()
        except OSError as exc:
            raise storage_error(exc, self.path, self.what) from None
        finally:
            del data
