"""`quadtank serve`: the lab from a browser (serve/; docs/serve.md).

Refused in one line, exit 2, before anything listens: another address than the
loopback without TLS or a trusted proxy, a certificate without its key, a program
that could not start tabs as their users (neither root nor CAP_SETUID and
CAP_SETGID), lab-file accounts from a lab file the administrators do not keep.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import signal
import sys
from pathlib import Path
from typing import Any

from quadtank_tui.commands import UsageError

#: CAP_SETGID and CAP_SETUID's bits in /proc/self/status's CapEff.
CAP_SETGID, CAP_SETUID = 6, 7


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("serve", help="the lab's TUI in a browser, with logins; each tab runs as its user",
                       description="Serve the TUI over HTTP(S): a login (the machine's accounts through PAM, "
                       "or the lab file's argon2 accounts), then each browser tab runs `quadtank` as the "
                       "user who logged in. Closing a tab detaches from the session. See docs/serve.md.")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1; another one needs --tls-cert/--tls-key or "
                   "--trusted-proxy)")
    p.add_argument("--port", type=int, default=8000, help="TCP port (default 8000)")
    p.add_argument("--tls-cert", metavar="FILE", help="TLS certificate (PEM) for https:// and wss://")
    p.add_argument("--tls-key", metavar="FILE", help="the certificate's private key (PEM)")
    p.add_argument("--lab", metavar="FILE", help="the lab file (default $QUADTANK_LAB, else /etc/quadtank/lab.yaml); "
                   "the tabs use it too")
    p.add_argument("--trusted-proxy", metavar="ADDRESS",
                   help="a reverse proxy's address: its X-Forwarded-For and X-Forwarded-Proto are believed, "
                   "from it only (default: the lab file's serve.trusted_proxy)")
    p.add_argument("--public-url", metavar="URL",
                   help="the address people type, https://HOST[:PORT] (the only Origin allowed; default: "
                   "the lab file's serve.public_url, else the Host of each request among this server's names)")
    p.add_argument("--audit", metavar="FILE", help="the audit log (default: the lab file's serve.audit_log, "
                   "else /var/log/quadtank/serve-audit.log)")
    p.add_argument("--hash-password", action="store_true",
                   help="read a password on stdin and print its argon2 hash for the lab file's serve.accounts; "
                   "serve nothing")
    p.set_defaults(handler=cmd_serve)


def cmd_serve(args: argparse.Namespace) -> int:
    if args.hash_password:
        from quadtank_tui.serve.auth import hash_password

        password = sys.stdin.readline().rstrip("\n")
        if not password:
            raise UsageError("--hash-password: give the password on stdin (one line)")
        print(hash_password(password))
        return 0
    server, site_args = prepare(args)
    return run(server, *site_args)


def has_switch_rights() -> bool:
    """Root, or both CAP_SETUID and CAP_SETGID in effect."""
    if os.geteuid() == 0:
        return True
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("CapEff:"):
                caps = int(line.split()[1], 16)
                return bool(caps >> CAP_SETUID & 1 and caps >> CAP_SETGID & 1)
    except (OSError, ValueError):
        pass
    return False


def prepare(args: argparse.Namespace) -> tuple[Any, tuple[str, int, Any]]:
    """The checked server and where it listens; UsageError for any refusal."""
    import ssl

    from quadtank_tui.serve.audit import AuditLog
    from quadtank_tui.serve.web_config import check_proxy, check_public_url, serve_settings
    from quadtank_tui.serve.web import Server, ServeOptions
    from quadtank_tui.session.lab import LabConfigError, load_lab_config
    from quadtank_tui.session.roles import untrusted_lab_file

    if not 1 <= args.port <= 65535:
        raise UsageError(f"--port must be 1..65535, got {args.port}")
    if bool(args.tls_cert) != bool(args.tls_key):
        raise UsageError("--tls-cert and --tls-key go together")
    try:
        lab = load_lab_config(args.lab)
        settings = serve_settings(lab)
    except LabConfigError as exc:
        raise UsageError(str(exc)) from None

    def bad(option: str):
        return lambda why: UsageError(f"{option}: {why}")

    proxy = check_proxy(args.trusted_proxy, bad("--trusted-proxy")) if args.trusted_proxy else settings.trusted_proxy
    url = check_public_url(args.public_url, bad("--public-url")) if args.public_url else settings.public_url
    try:
        addr = ipaddress.ip_address(args.host)
    except ValueError:
        raise UsageError(f"--host must be an IP address of this machine, got {args.host!r}") from None
    tls = None
    if args.tls_cert:
        tls = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        tls.minimum_version = ssl.TLSVersion.TLSv1_2
        try:
            tls.load_cert_chain(args.tls_cert, args.tls_key)
        except (OSError, ssl.SSLError) as exc:
            raise UsageError(f"--tls-cert/--tls-key: {exc}") from None
    proxy_only = False
    if not addr.is_loopback and tls is None:
        if proxy is None:
            raise UsageError(f"--host {args.host}: another address than the loopback needs TLS (--tls-cert and "
                             "--tls-key) or a reverse proxy (--trusted-proxy ADDRESS): passwords would cross the "
                             "network in clear (docs/serve.md)")
        proxy_only = True
    if settings.accounts and untrusted_lab_file(lab):
        raise UsageError(f"{untrusted_lab_file(lab)}: its serve.accounts are not used; an administrator keeps them "
                         "in the lab's own file")
    if not has_switch_rights():
        raise UsageError("quadtank serve starts each tab as the user who logged in: it needs root, or CAP_SETUID "
                         "and CAP_SETGID (docs/serve.md)")
    audit_path = Path(args.audit) if args.audit else settings.audit_log
    try:
        audit = AuditLog(audit_path, lab.admin_group)
    except OSError as exc:
        raise UsageError(f"the audit log: {exc}") from None
    passed = {k: os.environ[k] for k in ("QUADTANK_RUNTIME",) if os.environ.get(k)}
    if args.lab:
        passed["QUADTANK_LAB"] = str(Path(args.lab).resolve())
    elif os.environ.get("QUADTANK_LAB"):
        passed["QUADTANK_LAB"] = os.environ["QUADTANK_LAB"]
    from dataclasses import replace

    settings = replace(settings, trusted_proxy=proxy, public_url=url)
    options = ServeOptions(host=str(addr), port=args.port, tls=tls, settings=settings, passed_env=passed,
                           runtime=lab_runtime(lab).path, audit=audit, proxy_only=proxy_only)
    return Server(options), (str(addr), args.port, tls)


def lab_runtime(lab: Any) -> Any:
    """The lab's shared runtime folder, checked: every tab's user finds their
    sessions, locks and bookings there only if an administrator made it
    (`quadtank lab init`); without it each user would work alone in a folder of
    their own, and the server would list nobody's sessions."""
    from quadtank_tui.session.folders import RuntimeFolderError
    from quadtank_tui.session.lab import ensure_runtime_dir

    try:
        root = ensure_runtime_dir(lab)
    except RuntimeFolderError as exc:
        raise UsageError(str(exc)) from None
    if not root.lab:
        raise UsageError(f"{lab.runtime_dir}: not the lab's runtime folder ({root.note}); an administrator "
                         "makes it once with `quadtank lab init` before serving (docs/serve.md)")
    return root


def run(server: Any, host: str, port: int, tls: Any) -> int:
    """Serve until SIGINT or SIGTERM; open tabs are detached (never stopped) on the way out."""
    import asyncio  # here, not at the top: building the parser loads no event loop

    from aiohttp import web

    async def main() -> None:
        runner = web.AppRunner(server.app(), handle_signals=False, access_log=None)
        await runner.setup()
        site = web.TCPSite(runner, host, port, ssl_context=tls, reuse_address=True)
        try:
            await site.start()
        except OSError as exc:
            await runner.cleanup()
            raise UsageError(f"cannot listen on {host}:{port}: {exc.strerror}") from None
        scheme = "https" if tls else "http"
        shown = f"[{host}]" if ":" in host else host
        print(f"quadtank serve: listening on {scheme}://{shown}:{port}/ (Ctrl-C stops; open tabs detach)",
              flush=True)
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for signum in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(signum, stop.set)
        await stop.wait()
        await runner.cleanup()

    asyncio.run(main())
    return 0
