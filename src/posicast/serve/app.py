"""The designer's web application: one static page and a JSON API over posicast (Starlette).

Routes
------
``GET /``                 the page (``static/index.html``; its script and style under ``/static``)
``GET /api/kinds``        shaper kinds, their parameters; firmware and architecture menus
``POST /api/machine``     :func:`~posicast.serve.machine.machine_view`
``POST /api/design``      :func:`~posicast.serve.design.design_view`
``POST /api/export``      :func:`~posicast.serve.design.export_view` (a download)
``POST /api/loop``        :func:`~posicast.serve.loop.loop_view`
``POST /api/tune``        :func:`~posicast.serve.loop.tune_view`

Every request body is a JSON object of the form's fields.  Bad input (the library's
``ValueError``/``TypeError``, a :class:`~posicast.NoModeFound`, a root search that cannot be
certified) answers HTTP 400 with ``{"error": "<one line>"}``, the library's own message; an
unexpected exception answers 500 with one line too, never a traceback page.  The computations
run in Starlette's thread pool, so a long tuning does not block the page's other requests.
"""

from __future__ import annotations

import json
import logging
from importlib import metadata, resources
from typing import Any, Callable, Mapping

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from ..loops.architectures import ARCHITECTURES
from ..spectra.rootfinder import RootFindingError
from .design import design_view, export_view, kinds_view
from .loop import loop_view, tune_view
from .machine import FIRMWARE_CHOICES, MAX_UPLOAD, machine_view

__all__ = ["create_app", "STATIC"]

#: The page's files, shipped inside the package (no CDN, no build step).
STATIC = resources.files("posicast.serve") / "static"
_log = logging.getLogger("posicast.serve")


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _clean(x: Any) -> Any:
    """JSON has no NaN or infinity: null."""
    if isinstance(x, float):
        return x if x == x and abs(x) != float("inf") else None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


async def _form(request: Request) -> Mapping[str, Any]:
    body = await request.body()
    if len(body) > MAX_UPLOAD + 1_000_000:
        raise ValueError(f"the request has {len(body)} bytes; the designer reads at most {MAX_UPLOAD}")
    if not body.strip():
        raise ValueError("the request is empty: send the form's fields as a JSON object")
    try:
        form = json.loads(body)
    except ValueError:
        raise ValueError("the request is not JSON: send the form's fields as a JSON object") from None
    if not isinstance(form, dict):
        raise TypeError(f"the request must be a JSON object, got {type(form).__name__}")
    return form


def _endpoint(view: Callable[[Mapping[str, Any]], Any]) -> Callable[[Request], Any]:
    async def handle(request: Request) -> Response:
        try:
            form = await _form(request)
            result = await run_in_threadpool(view, form)
        except (ValueError, TypeError, RootFindingError) as exc:  # NoModeFound is a ValueError
            return JSONResponse({"error": _one_line(exc)}, status_code=400)
        except Exception as exc:  # a bug: one line for the page, the traceback in the server's log
            _log.exception("internal error in %s", request.url.path)
            return JSONResponse({"error": f"internal error: {type(exc).__name__}: {_one_line(exc)}"},
                                status_code=500)
        if isinstance(result, tuple):  # a download: (file name, text, media type)
            name, text, media = result
            return Response(text, media_type=media, headers={"Content-Disposition": f'attachment; filename="{name}"'})
        return JSONResponse(_clean(result))

    handle.__name__ = view.__name__
    return handle


async def _index(request: Request) -> Response:
    with resources.as_file(STATIC / "index.html") as path:
        return FileResponse(path, headers={"Cache-Control": "no-store"})


async def _kinds(request: Request) -> Response:
    out = kinds_view()
    out["firmwares"] = list(FIRMWARE_CHOICES)
    out["architectures"] = list(ARCHITECTURES)
    out["version"] = metadata.version("posicast")
    return JSONResponse(out)


def create_app() -> Starlette:
    """The designer as an ASGI application (serve it with uvicorn, test it with Starlette's TestClient).

    >>> from starlette.testclient import TestClient
    >>> client = TestClient(create_app())
    >>> client.post("/api/design", json={"kind": "zv", "modes": [{"freq_hz": "0", "zeta": "0"}]}).json()
    {'error': 'freq_hz must be > 0, got 0'}
    """
    with resources.as_file(STATIC) as static_dir:
        routes = [
            Route("/", _index),
            Route("/api/kinds", _kinds),
            Route("/api/machine", _endpoint(machine_view), methods=["POST"]),
            Route("/api/design", _endpoint(design_view), methods=["POST"]),
            Route("/api/export", _endpoint(export_view), methods=["POST"]),
            Route("/api/loop", _endpoint(loop_view), methods=["POST"]),
            Route("/api/tune", _endpoint(tune_view), methods=["POST"]),
            Mount("/static", app=StaticFiles(directory=str(static_dir)), name="static"),
        ]
    return Starlette(routes=routes)
