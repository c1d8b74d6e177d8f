"""What the file formats offer their users for files: regular files only, atomic writes.

The public surface of :mod:`data_formats._files` (reading: a path must be a regular file, not a
FIFO or a device, :func:`open_regular`, :class:`NotRegularFileError`, :func:`describe_mode`) and
:mod:`data_formats._atomic` (writing: a file appears complete or not at all,
:func:`atomic_write`, :func:`atomic_path`; writes in flight, :func:`writing`, closed and opened
again by a program that must end at once, :func:`close_writes`, :func:`open_writes`). Code
outside ``data_formats`` imports these names from here.
"""

from ._atomic import atomic_path, atomic_write, close_writes, open_writes, writing
from ._files import NotRegularFileError, describe_mode, open_regular

__all__ = ["NotRegularFileError", "atomic_path", "atomic_write", "close_writes",
           "describe_mode", "open_regular", "open_writes", "writing"]
