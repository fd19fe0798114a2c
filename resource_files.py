"""Files shipped under resources/ (icons, QML styles, Processing models), shared by plugin/ and ui/."""

import os


def resource_path(*parts):
    """Absolute path of a file under resources/."""
    return os.path.join(os.path.dirname(__file__), "resources", *parts)
