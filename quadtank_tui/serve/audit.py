"""The server's audit log: one line per login, logout, failed login, tab (attach,
observe, take-over, new session) and session stop, for the administrators only.

The file is created 0640 with the lab's admin_group as its group (0600 root's
without one), appended with O_APPEND, and never followed through a link; the
folder it is in must not be writable by others (a student could replace it).
Each line: an ISO time in UTC, the event, then key=value fields; values are
quoted where they hold spaces, and a control character never reaches the file.
"""

from __future__ import annotations

import grp
import os
import stat
import time
from pathlib import Path


class AuditLog:
    def __init__(self, path: Path, admin_group: str | None) -> None:
        self.path = path
        self.gid: int | None = None
        if admin_group:
            try:
                self.gid = grp.getgrnam(admin_group).gr_gid
            except KeyError:
                self.gid = None
        folder = path.parent
        folder.mkdir(parents=True, exist_ok=True, mode=0o750)
        st = os.lstat(folder)
        if not stat.S_ISDIR(st.st_mode) or st.st_mode & 0o022 or st.st_uid not in (0, os.getuid()):
            raise PermissionError(f"{folder}: the audit log's folder must be a folder of root's or the "
                                  "server's, writable by no one else")
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        try:
            fst = os.fstat(fd)
            if not stat.S_ISREG(fst.st_mode):
                raise PermissionError(f"{path}: the audit log is not a plain file")
            if self.gid is not None:
                os.fchown(fd, -1, self.gid)
                os.fchmod(fd, 0o640)
            else:
                os.fchmod(fd, 0o600)
        except BaseException:
            os.close(fd)
            raise
        self._fd = fd

    def write(self, event: str, **fields: object) -> None:
        parts = [time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), event]
        for key, value in fields.items():
            if value is None:
                continue
            text = "".join(c if c.isprintable() else "?" for c in str(value))[:200]
            if not text or any(c in text for c in ' "='):
                text = '"' + text.replace('"', "'") + '"'
            parts.append(f"{key}={text}")
        os.write(self._fd, (" ".join(parts) + "\n").encode("utf-8", "replace"))

    def close(self) -> None:
        os.close(self._fd)
