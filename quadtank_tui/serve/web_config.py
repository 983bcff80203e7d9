"""The lab file's `serve:` section: how `quadtank serve` lets people in.

```yaml
serve:
  pam: true                    # the machine's accounts, checked by PAM (default true)
  pam_service: quadtank        # /etc/pam.d/quadtank (absent: PAM's `other`)
  accounts:                    # lab-file logins: name -> argon2 hash (quadtank serve --hash-password)
    alice: "$argon2id$v=19$m=65536,t=3,p=4$..."   # each name is an account of this machine
  idle_minutes: 30             # a login ends after this long without use
  max_hours: 12                # and this long after it began, whatever happens
  audit_log: /var/log/quadtank/serve-audit.log
  trusted_proxy: 127.0.0.1     # a reverse proxy whose X-Forwarded-For/-Proto are believed
  public_url: https://rig7.lab.example.org   # the address people type (the only Origin allowed)
  heartbeat_seconds: 20        # websocket pings; a tab silent for 1.5 times this is closed (detached)
```

Lab-file accounts count only from a lab file the administrators keep (root's,
written by no one else: session/roles.untrusted_lab_file); a student's own
QUADTANK_LAB file gives no logins.
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping
from urllib.parse import urlsplit

from quadtank_tui.session.lab import LabConfig, LabConfigError

KEYS = ("pam", "pam_service", "accounts", "idle_minutes", "max_hours", "audit_log", "trusted_proxy",
        "public_url", "heartbeat_seconds")
DEFAULT_AUDIT = Path("/var/log/quadtank/serve-audit.log")


@dataclass(frozen=True)
class ServeSettings:
    pam: bool = True
    pam_service: str = "quadtank"
    accounts: Mapping[str, str] = field(default_factory=dict)
    idle_minutes: float = 30.0
    max_hours: float = 12.0
    audit_log: Path = DEFAULT_AUDIT
    trusted_proxy: str | None = None
    public_url: str | None = None
    heartbeat_seconds: float = 20.0


def serve_settings(lab: LabConfig) -> ServeSettings:
    """The `serve:` section of `lab`, checked (LabConfigError naming file, line and key)."""
    data: Mapping[str, Any] = lab.sections.get("serve", {})
    name = str(lab.source) if lab.source else "<lab config>"

    def fail(key: str, reason: str) -> LabConfigError:
        return LabConfigError(name, reason, key=f"serve.{key}", line=lab.lines.get(f"serve.{key}",
                                                                                    lab.lines.get("serve")))

    for k in data:
        if k not in KEYS:
            raise fail(str(k), f"unknown key; expected one of {', '.join(KEYS)}")
    pam = data.get("pam", True)
    if not isinstance(pam, bool):
        raise fail("pam", "must be true or false")
    service = data.get("pam_service", "quadtank")
    if not isinstance(service, str) or not service.replace("-", "").replace("_", "").isalnum():
        raise fail("pam_service", "must be the name of a PAM service (a file of /etc/pam.d)")
    accounts = data.get("accounts") or {}
    if not isinstance(accounts, dict):
        raise fail("accounts", "must map user names to argon2 hashes")
    for user, hashed in accounts.items():
        if not isinstance(user, str) or not user or not isinstance(hashed, str) or not hashed.startswith("$argon2"):
            raise fail(f"accounts.{user}", "must be a user name and an argon2 hash "
                       "(quadtank serve --hash-password makes one)")
    idle = _number(data, "idle_minutes", 30.0, 1.0, 24 * 60.0, fail)
    maximum = _number(data, "max_hours", 12.0, 0.05, 24 * 7.0, fail)
    audit = data.get("audit_log")
    if audit is not None and (not isinstance(audit, str) or not audit.startswith("/")):
        raise fail("audit_log", "must be an absolute file path")
    proxy = data.get("trusted_proxy")
    if proxy is not None:
        proxy = check_proxy(str(proxy), lambda why: fail("trusted_proxy", why))
    url = data.get("public_url")
    if url is not None:
        url = check_public_url(str(url), lambda why: fail("public_url", why))
    heartbeat = _number(data, "heartbeat_seconds", 20.0, 1.0, 300.0, fail)
    return ServeSettings(pam, service, dict(accounts), idle, maximum, Path(audit) if audit else DEFAULT_AUDIT,
                         proxy, url, heartbeat)


def _number(data: Mapping[str, Any], key: str, default: float, low: float, high: float, fail: Any) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
        raise fail(key, f"must be a number {low:g}..{high:g}, got {value!r}")
    return float(value)


def check_proxy(text: str, fail: Any) -> str:
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        raise fail(f"must be the proxy's IP address (its requests' source), got {text!r}") from None


def check_public_url(text: str, fail: Any) -> str:
    parts = urlsplit(text)
    if parts.scheme not in ("http", "https") or not parts.hostname or parts.path not in ("", "/") \
            or parts.query or parts.fragment or parts.username:
        raise fail(f"must be http(s)://HOST[:PORT] with nothing after, got {text!r}")
    return f"{parts.scheme}://{parts.netloc}"
