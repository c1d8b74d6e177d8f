"""Opening input files safely: regular files only, checked before and after opening.

A FIFO blocks ``open()`` until a writer appears, and a character device (``/dev/zero``,
``/dev/urandom``, a symlink to either) never ends, so a reader that trusted the path would hang
or fill memory. :func:`open_regular` refuses anything that is not a regular file: it looks at
the path with ``stat`` (following symlinks) before opening, opens with ``O_NONBLOCK`` (so a
FIFO swapped in after the check cannot block), and checks the open descriptor with ``fstat``
(so what is read is what was checked).
"""

from __future__ import annotations

import fcntl
import os
import stat

__all__ = ["NotRegularFileError", "open_regular", "describe_mode"]


class NotRegularFileError(OSError):
    """The path exists but is not a regular file (a FIFO, a device, a socket, a directory).

    ``filename`` is the path, ``what`` says what it is (``"a FIFO (named pipe)"``).
    """

    def __str__(self) -> str:
        return self.args[0]


def describe_mode(mode: int) -> str:
    """``"a FIFO"``, ``"a character device"``, ... for a ``st_mode``."""
    for test, what in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return what
    return "not a regular file"


def _refuse(path, mode: int) -> NotRegularFileError:
    what = describe_mode(mode)
    exc = NotRegularFileError(f"{os.fspath(path)}: is {what}, not a regular file; "
                              f"copy the data into a file and pass that")
    exc.filename, exc.what = os.fspath(path), what
    return exc


def open_regular(path, mode: str = "rb", **kwargs):
    """``open(path, mode)`` for a regular file; :class:`NotRegularFileError` for anything else.

    ``FileNotFoundError`` and ``PermissionError`` propagate as ``open`` raises them.
    ``mode`` is a read mode (``"rb"`` or ``"r"`` with ``encoding=...``).
    """
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise _refuse(path, st.st_mode)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise _refuse(path, st.st_mode)
        flags = fcntl.fcntl(fd, fcntl.F_GETFL)
        fcntl.fcntl(fd, fcntl.F_SETFL, flags & ~os.O_NONBLOCK)
        return open(fd, mode, **kwargs)
    except BaseException:
        os.close(fd)
        raise
