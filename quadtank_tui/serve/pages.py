"""The two pages: the login form, and the app's page (textual-serve's, made
self-contained: no font or script from elsewhere, so a lab without Internet and a
strict Content-Security-Policy both work)."""

from __future__ import annotations

from html import escape

STYLE = """
html, body { height: 100%; overflow: hidden; }
body { background: #0c181f; color: #e0e0e0; font-family: menlo, "DejaVu Sans Mono", monospace; margin: 0; }
.bar { display: flex; gap: 1.5em; align-items: center; height: 24px; box-sizing: border-box; padding: 0 10px; background: #12232d; font-size: 14px; }
.bar a, .bar button { color: #ffa62b; background: none; border: none; font: inherit; cursor: pointer; padding: 0; }
.bar form { display: inline; margin: 0; }
.login { max-width: 26em; margin: 12vh auto; padding: 2em; background: #12232d; }
.login input { display: block; width: 100%; margin: 0.3em 0 1em; padding: 0.4em; font: inherit; box-sizing: border-box; }
.login button { padding: 0.5em 2em; font: inherit; background: #5e0ba7; color: #fff; border: none; }
.error { color: #ff7070; }
"""

APP_STYLE = """
@font-face { font-family: "Roboto Mono"; src: url("/static/fonts/RobotoMono-VariableFont_wght.ttf"); }
.dialog-container { position: absolute; width: 100vw; height: 100vh; display: flex; align-items: center;
  justify-content: center; z-index: 10; top: 0; left: 0; }
.intro { width: 640px; padding: 2em; z-index: 20; text-align: center; background-color: #12232d; }
body.-first-byte .intro-dialog { display: none; }
body .textual-terminal { opacity: 0; }
body.-first-byte .textual-terminal { opacity: 1; }
.closed-dialog { display: none; }
body.-closed .closed-dialog { display: flex; }
#start { display: none; }
#start.-delay { display: flex; }
/* textual.js's own stylesheet makes .textual-terminal 100vw x 100vh, which beats top/bottom:
   the terminal then ran 24px under the window's edge and its last row (the footer) was cut */
#terminal { position: absolute; top: 24px; bottom: 12px; left: 0; right: 0; overflow: hidden;
  width: auto; height: auto; }
"""


def login_page(message: str = "", user: str = "") -> str:
    error = f'<p class="error">{escape(message)}</p>' if message else ""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>quadtank: log in</title>
<style>{STYLE}</style></head>
<body><form class="login" method="post" action="/login">
<h2>Quadruple tank lab</h2>{error}
<label>User <input name="user" autocomplete="username" value="{escape(user)}" autofocus></label>
<label>Password <input name="password" type="password" autocomplete="current-password"></label>
<button type="submit">Log in</button>
</form></body></html>
"""


def app_page(*, user: str, websocket_url: str, what: str, sessions: list[tuple[str, str]],
             font_size: int = 16) -> str:
    """The terminal's page; `sessions`: (id, link) of the user's running sessions,
    each a way back in (attach)."""
    links = " ".join(f'<a href="{escape(link)}">{escape(sid)}</a>' for sid, link in sessions)
    mine = f"<span>your sessions: {links}</span>" if links else "<span>no running session</span>"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>quadtank: {escape(user)}</title>
<link rel="stylesheet" href="/static/css/xterm.css">
<script src="/static/js/textual.js"></script>
<style>{STYLE}{APP_STYLE}</style>
<script>
// xterm measures its cells when it opens, maybe before the terminal's font has loaded: once
// it has, a resize makes textual.js fit the terminal again (and tell the TUI its size)
window.addEventListener("load", () => {{
  document.fonts.load("16px 'Roboto Mono'").finally(() => setTimeout(() => window.dispatchEvent(new Event("resize")), 50));
  setTimeout(() => window.dispatchEvent(new Event("resize")), 1500);
}});
</script></head>
<body>
<div class="bar"><span>quadtank &middot; {escape(user)}</span><span>{escape(what)}</span>{mine}
<a href="/">attach</a>
<form method="post" action="/logout"><button type="submit">log out</button></form></div>
<div class="dialog-container intro-dialog"><div class="intro"><div>quadtank</div>
<button type="button" onclick="location.reload()" id="start">Start</button></div></div>
<div class="dialog-container closed-dialog"><div class="intro">
<div class="message">The screen has closed; the session goes on.</div>
<button type="button" onclick="location.reload()">Attach again</button></div></div>
<div id="terminal" class="textual-terminal" data-session-websocket-url="{escape(websocket_url)}"
 data-font-size="{font_size}"></div>
</body></html>
"""
