"""Which file a path names, whatever the name: its real path (symbolic links resolved) and, where it exists,
its (device, inode), which a hard link shares. Two paths name one file where either agrees."""

import os
from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class FileIdentity:
    """A path resolved: its real path and, where it exists, its (device, inode)."""

    real: str
    inode: Optional[tuple]

    @classmethod
    def of(cls, path) -> "FileIdentity":
        real = os.path.realpath(os.fspath(path))
        try:
            st = os.stat(real)
        except (OSError, ValueError):
            return cls(real, None)
        return cls(real, (st.st_dev, st.st_ino))

    @property
    def key(self):
        """A key one file has under every name: its (device, inode), else its real path (a path that does not
        exist)."""
        return self.inode if self.inode is not None else self.real

    def same(self, other: "FileIdentity") -> bool:
        return self.real == other.real or (self.inode is not None and self.inode == other.inode)

    def inside(self, folder: "FileIdentity") -> bool:
        """Whether this path lies below `folder`."""
        return self.real.startswith(folder.real.rstrip(os.sep) + os.sep)
