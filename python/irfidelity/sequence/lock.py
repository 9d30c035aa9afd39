"""``PATH.lock``: one writer of a CSV at a time.

An exclusive, non-blocking ``flock`` on the lock file, which holds the writer's process id
(for the message a second run gets). The lock dies with its process (a killed run leaves a
file, not a lock). A finished run removes the file while it still holds the lock, so the
protocol is the usual one for removable lock files: after locking, a run checks that the
path still names the file it locked (the one it opened may have been removed by the run
that held it), and opens the path again if not. So two runs never hold locks on different
files for the same CSV, and a run removes only the file it holds.
"""

from __future__ import annotations

import os
from typing import IO

from ..errors import FidelityError

__all__ = ["Lock"]

_ATTEMPTS = 100  # a lock file removed under a waiting run every time is not a real case


def _same_file(fh: IO[str], path: str) -> bool:
    try:
        now, held = os.stat(path), os.fstat(fh.fileno())
    except OSError:
        return False
    return (now.st_dev, now.st_ino) == (held.st_dev, held.st_ino)


class Lock:
    """The lock of ``path`` (the ``.lock`` file of a CSV), taken at once or refused with a
    FidelityError naming the run holding it."""

    def __init__(self, path: str):
        self.path = path
        try:
            import fcntl
        except ImportError:  # no flock (Windows): no locking
            self.fh: IO[str] | None = None
            return
        for _ in range(_ATTEMPTS):
            fh = open(path, "a+")  # noqa: SIM115 (held, locked, until release())
            try:
                fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                fh.seek(0)
                holder = fh.read(64).strip() or "unknown"
                fh.close()
                raise FidelityError(f"{path[:-5]}: another irfidelity run (process {holder}) is writing this CSV; "
                                    f"wait for it to finish, or write to another CSV", option="csv") from None
            if _same_file(fh, path):
                break
            fh.close()  # locked a file its holder removed: lock the one the path names now
        else:
            raise FidelityError(f"{path}: this lock file keeps being replaced; cannot lock the CSV", option="csv")
        fh.seek(0)
        fh.truncate()
        fh.write(str(os.getpid()))
        fh.flush()
        self.fh = fh

    def release(self) -> None:
        """Remove the lock file if it is still the one held, then unlock (idempotent)."""
        fh, self.fh = self.fh, None
        if fh is None or fh.closed:
            return
        try:
            if _same_file(fh, self.path):
                os.unlink(self.path)
        except OSError:
            pass  # already gone, or not ours to remove: the lock itself ends below
        finally:
            fh.close()
