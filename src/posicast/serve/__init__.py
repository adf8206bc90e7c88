"""``posicast serve``: the interactive designer in the browser (issue #20), local and offline.

Three tabs over posicast's public functions: *machine* (a Klipper resonance test or typed modes
-> :func:`posicast.calibrate`'s spectrum, modes, candidate shapers and config lines), *design*
(modes and a shaper family -> :func:`posicast.design`'s impulses, sensitivity, sampled taps and
:func:`posicast.export_shaper`), *loop* (plant, controller, shaper -> :func:`posicast.stability`,
the spectrum, :func:`posicast.simulate`'s responses, :func:`posicast.tune_pd` / ``tune_pi``).
The server computes everything; the page (plain HTML, CSS and JavaScript shipped in
``static/``, no build step, nothing fetched from the internet) only sends the forms and shows
the answers.  The web stack (Starlette, uvicorn) is the optional extra ``posicast[serve]``;
this module imports neither until :func:`serve` runs.
"""

from __future__ import annotations

import importlib.util
import json
import os
import threading
import webbrowser

__all__ = ["REQUIREMENTS", "missing_requirements", "serve"]

#: The extra's packages (import names).
REQUIREMENTS = ("starlette", "uvicorn")


def missing_requirements() -> list[str]:
    """The packages of the ``serve`` extra that are not installed.

    >>> missing_requirements() in ([], ["starlette"], ["uvicorn"], ["starlette", "uvicorn"])
    True
    """
    return [name for name in REQUIREMENTS if importlib.util.find_spec(name) is None]


def serve(host: str = "127.0.0.1", port: int = 8765, open_browser: bool = True, json_line: bool = False) -> None:
    """Run the designer at ``http://host:port/`` until interrupted (Ctrl-C).

    Parameters
    ----------
    host : str
        Address to listen on; the default answers this machine only.
    port : int
        TCP port, 0 for any free one.
    open_browser : bool
        Open the page in the default browser once the server listens.
    json_line : bool
        Announce the address as one JSON line ``{"url", "host", "port", "pid"}`` instead of a sentence
        (a script that started the designer on port 0 reads where it listens).
    """
    import uvicorn  # the optional extra: imported only when the designer runs

    from .app import create_app

    config = uvicorn.Config(create_app(), host=host, port=port, log_level="warning")
    server = uvicorn.Server(config)

    def announce() -> None:  # once listening: the real port (port 0 picks one)
        while not server.started:
            if server.should_exit:
                return
            threading.Event().wait(0.05)
        sock = server.servers[0].sockets[0].getsockname() if server.servers else (host, port)
        url = f"http://{'localhost' if host in ('127.0.0.1', '0.0.0.0') else host}:{sock[1]}/"
        if json_line:
            print(json.dumps({"url": url, "host": host, "port": sock[1], "pid": os.getpid()}), flush=True)
        else:
            print(f"posicast designer at {url} (Ctrl-C stops it)", flush=True)
        if open_browser:
            webbrowser.open(url)

    threading.Thread(target=announce, daemon=True).start()
    server.run()
