"""What a folder holds, byte for byte: to assert that a step left its inputs or a block as they were."""

import hashlib
import os


def fingerprint(folder):
    """{path relative to `folder`: SHA-256 of its bytes, or 'folder'} of everything below `folder`."""
    found = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs:
            found[os.path.relpath(os.path.join(root, name), folder)] = "folder"
        for name in files:
            path = os.path.join(root, name)
            with open(path, "rb") as f:
                found[os.path.relpath(path, folder)] = hashlib.sha256(f.read()).hexdigest()
    return found
