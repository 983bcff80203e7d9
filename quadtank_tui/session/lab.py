"""The lab configuration: a small YAML file an administrator keeps (by default
/etc/quadtank/lab.yaml) that says who administers the lab, where the sessions'
sockets and the DAQ locks live, and what an unattended Active session does.

```yaml
admin_group: teachers        # members may save default.par, set the policy, take over
share_group: lab             # may connect to others' sessions (omit: owner + admins only)
runtime_dir: /run/quadtank   # sockets, session records, locks/ (default /tmp/quadtank-sessions)
defaults: /opt/quadtank/params   # the folder of the lab's default.par (default: the
                                 # installation's params/, never the current folder)
unattended:
  keep_while_logging: true
  grace_minutes: 10
```

Every key is optional.  The file is read like the DAQ configurations (size and
alias limits, files.yamltext); an unknown key, a wrong type or a value out of range
is refused with the file, the line and the key.  No file: the defaults.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping


from quadtank_tui.files.yamltext import key_lines, parse_yaml, read_text
from quadtank_tui.session.folders import Root
from quadtank_tui.session.policy import MAX_GRACE_MINUTES, UnattendedPolicy

#: The lab file read when neither a path nor $QUADTANK_LAB is given.
SYSTEM_LAB_FILE = Path("/etc/quadtank/lab.yaml")
#: The runtime folder when neither the lab file nor $QUADTANK_RUNTIME names one.
DEFAULT_RUNTIME_DIR = Path("/tmp/quadtank-sessions")
#: Where the lab's default.par lives unless the lab file says `defaults:`: the
#: installation's params/ (next to the package), whose writers are the
#: administrators when no `admin_group` is set.  Never the current folder: a
#: student in a folder of their own may write its params/default.par, and was an
#: administrator of the lab for it (issue 24).
DEFAULT_PARAMS_DIR = Path(__file__).resolve().parents[2] / "params"

KEYS = ("admin_group", "share_group", "runtime_dir", "defaults", "unattended", "serve", "bookings")
#: Sections whose keys their own readers check (serve/web_config.py, session/bookings.py):
#: here only that each is a mapping; LabConfig.sections holds them with their lines.
SECTIONS = ("serve", "bookings")
POLICY_KEYS = ("keep_while_logging", "grace_minutes")


class LabConfigError(ValueError):
    """A lab configuration refused; the message names the file, line and key."""

    def __init__(self, file: str, reason: str, *, key: str | None = None, line: int | None = None) -> None:
        where = file if line is None else f"{file}:{line}"
        super().__init__(f"{where}: {key}: {reason}" if key else f"{where}: {reason}")
        self.file, self.key, self.line, self.reason = file, key, line, reason


@dataclass(frozen=True)
class LabConfig:
    """The lab's rules in force; see the module docstring for each key."""

    admin_group: str | None = None
    runtime_dir: Path = DEFAULT_RUNTIME_DIR
    share_group: str | None = None
    unattended: UnattendedPolicy = field(default_factory=UnattendedPolicy)
    #: the file it was read from (None: the defaults, no file)
    source: Path | None = None
    #: the folder holding the lab's default.par
    params_dir: Path = DEFAULT_PARAMS_DIR
    #: the `serve:` and `bookings:` sections as written (their readers check them)
    sections: Mapping[str, Mapping[str, Any]] = field(default_factory=dict, compare=False)
    #: dotted key -> line in the file, for those readers' messages
    lines: Mapping[str, int] = field(default_factory=dict, compare=False)
    #: who named runtime_dir: "lab file", "env" ($QUADTANK_RUNTIME), "default" (nobody:
    #: DEFAULT_RUNTIME_DIR), "named" (a program, a test): see session/folders.resolve
    runtime_source: str = "named"

    @property
    def locks_dir(self) -> Path:
        """Where the DAQ locks are (one record per device, each owned by its writer):
        locks/ of the runtime folder in force (session/folders.py)."""
        return ensure_runtime_dir(self).locks

    @property
    def default_par(self) -> Path:
        return self.params_dir / "default.par"


def lab_file_path(path: Path | str | None = None) -> tuple[Path, bool]:
    """(the lab file to read, whether it was named explicitly): `path`, else
    $QUADTANK_LAB, else /etc/quadtank/lab.yaml.  A file named explicitly must
    exist; the system one may be absent (then the defaults hold)."""
    if path is not None:
        return Path(path), True
    env = os.environ.get("QUADTANK_LAB")
    if env:
        return Path(env), True
    return SYSTEM_LAB_FILE, False


def default_runtime_dir() -> Path:
    env = os.environ.get("QUADTANK_RUNTIME")
    return Path(env) if env else DEFAULT_RUNTIME_DIR


def _default_source() -> str:
    return "env" if os.environ.get("QUADTANK_RUNTIME") else "default"


def load_lab_config(path: Path | str | None = None) -> LabConfig:
    """The lab configuration in force (see lab_file_path); LabConfigError for a
    bad file, or an explicitly named one that is missing."""
    file, explicit = lab_file_path(path)
    if not explicit and not file.exists():
        return LabConfig(runtime_dir=default_runtime_dir(), runtime_source=_default_source())
    return parse_lab_config(read_text(file, _error), name=str(file), source=file)


def _error(name: str, message: str, line: int | None) -> LabConfigError:
    return LabConfigError(name, message, line=line)


def parse_lab_config(text: str, *, name: str = "<lab config>", source: Path | None = None) -> LabConfig:
    """Validate the YAML `text` (named `name` in errors)."""
    node, data = parse_yaml(text, name, _error)
    lines = key_lines(node)

    def fail(key: str, reason: str) -> LabConfigError:
        return LabConfigError(name, reason, key=key, line=lines.get(key, lines.get(key.split(".")[0])))

    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise LabConfigError(name, "must be a mapping of keys (admin_group: ..., runtime_dir: ...)", line=1)
    _known(data, "", KEYS, fail)
    base = source.parent if source is not None else Path.cwd()
    policy = data.get("unattended", {})
    if policy is None:
        policy = {}
    if not isinstance(policy, dict):
        raise fail("unattended", f"must be a mapping (keep_while_logging: ..., grace_minutes: ...), got {_show(policy)}")
    _known(policy, "unattended.", POLICY_KEYS, fail)
    keep = policy.get("keep_while_logging", UnattendedPolicy.keep_while_logging)
    if not isinstance(keep, bool):
        raise fail("unattended.keep_while_logging", f"must be true or false, got {_show(keep)}")
    grace = policy.get("grace_minutes", UnattendedPolicy.grace_minutes)
    if isinstance(grace, bool) or not isinstance(grace, (int, float)) or not 0 <= grace <= MAX_GRACE_MINUTES:
        raise fail("unattended.grace_minutes", f"must be a number of minutes 0..{MAX_GRACE_MINUTES:g}, "
                   f"got {_show(grace)}")
    runtime = _path(data, "runtime_dir", base, fail)
    params = _path(data, "defaults", base, fail)
    sections: dict[str, Mapping[str, Any]] = {}
    for key in SECTIONS:
        value = data.get(key)
        if value is not None and not isinstance(value, dict):
            raise fail(key, f"must be a mapping of keys, got {_show(value)}")
        sections[key] = value or {}
    return LabConfig(
        admin_group=_group(data, "admin_group", fail),
        runtime_dir=runtime if runtime is not None else default_runtime_dir(),
        runtime_source="lab file" if runtime is not None else _default_source(),
        share_group=_group(data, "share_group", fail),
        unattended=UnattendedPolicy(keep, float(grace)),
        source=source,
        params_dir=params if params is not None else DEFAULT_PARAMS_DIR,
        sections=sections,
        lines=lines,
    )


def _known(m: Mapping[Any, Any], prefix: str, allowed: tuple[str, ...], fail: Any) -> None:
    for k in m:
        if not isinstance(k, str) or k not in allowed:
            raise fail(f"{prefix}{k}", f"unknown key; expected one of {', '.join(allowed)}")


def _group(data: Mapping[str, Any], key: str, fail: Any) -> str | None:
    value = data.get(key)
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip() or any(c.isspace() or c == ":" for c in value):
        raise fail(key, f"must be the name of an operating-system group, got {_show(value)}")
    return value


def _path(data: Mapping[str, Any], key: str, base: Path, fail: Any) -> Path | None:
    """A folder named in the file; relative ones are taken from the file's folder."""
    value = data.get(key)
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip() or "\0" in value:
        raise fail(key, f"must be a folder path, got {_show(value)}")
    p = Path(value).expanduser()
    return p if p.is_absolute() else base / p


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def with_policy(text: str, policy: UnattendedPolicy) -> str:
    """The lab file's `text` with its `unattended:` block replaced by `policy` (or
    the block added at the end); the rest of the file, comments included, as it was."""
    block = [
        "unattended:\n",
        f"  keep_while_logging: {'true' if policy.keep_while_logging else 'false'}\n",
        f"  grace_minutes: {policy.grace_minutes:g}\n",
    ]
    lines = text.splitlines(keepends=True)
    start = next((i for i, line in enumerate(lines) if re.match(r"unattended\s*:", line)), None)
    if start is None:
        return text + ("\n" if text and not text.endswith("\n") else "") + "".join(block)
    end = start + 1
    while end < len(lines) and (lines[end][:1] in (" ", "\t") or not lines[end].strip()):
        end += 1
    while end > start + 1 and not lines[end - 1].strip():
        end -= 1  # blank lines after the block stay
    return "".join(lines[:start] + block + lines[end:])


# --- the runtime folder -------------------------------------------------------------------

def ensure_runtime_dir(lab: LabConfig) -> Root:
    """The runtime folder in force for `lab`, checked (and made where it is ours
    to make): session/folders.resolve, with the lab's administrators."""
    from quadtank_tui.session.folders import resolve
    from quadtank_tui.session.roles import is_administrator

    return resolve(lab.runtime_dir, source=lab.runtime_source, admin=lambda uid: is_administrator(uid, lab))
