"""The engine's exception types. Every user-facing failure raises one of these with a message
that says what is wrong and what to do; the Processing layer turns them into
QgsProcessingException."""


class PushbroomError(Exception):
    """Base class of all errors the engine raises on purpose."""


class MetadataError(PushbroomError):
    """Orientation metadata (DIMAP, RPC, model file) is unreadable, incomplete or inconsistent."""


class InputError(PushbroomError):
    """A parameter or a data set handed to the engine cannot be used as given."""


class GeometryError(PushbroomError):
    """A geometric computation has no answer (point outside the scene, ray misses the DEM,
    iteration did not converge)."""


class StorageError(PushbroomError):
    """A file or the block cannot be written or read as stored: no permission, no space, a read-only or
    missing folder, a block locked by another program, a damaged or foreign file. The message names the
    path and what to do."""


class ExecutionError(PushbroomError):
    """Tile tasks could not run where they were sent: no scheduler at the address, a worker process
    died, no Python interpreter to start workers with. The message says what to change."""


class CancelledError(PushbroomError):
    """The user cancelled a long step; nothing half-done was written under a final name."""
