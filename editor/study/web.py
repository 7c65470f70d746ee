"""The rating page for remote raters: a Starlette (ASGI) app over one study file (no Qt).

Every URL carries the rater's invite token: ``/r/TOKEN/`` (the page), ``/r/TOKEN/app.js`` and
``app.css`` (from the package data, ``editor/data/web``), ``/r/TOKEN/api/state``,
``POST /r/TOKEN/api/answer`` and ``/r/TOKEN/img/POSITION``. No token, an unknown or a revoked
one: 403 and nothing is written. Each token may make :data:`DEFAULT_RATE_LIMIT` requests
(moving window, the ``limits`` package), then 429. The store work (:mod:`editor.study.remote`)
runs on one dedicated thread with one SQLite connection: each request is a few indexed queries
and at most one committed transaction, and requests never interleave inside one.
``fap-studio study serve`` runs the app with uvicorn.
"""

from __future__ import annotations

import asyncio
import json
import socket
from collections.abc import AsyncIterator, Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from limits import parse
from limits.storage import MemoryStorage
from limits.strategies import MovingWindowRateLimiter
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import JSONResponse, RedirectResponse, Response
from starlette.routing import Route

from editor.errors import StudyError
from editor.resources import WEB_DIR
from editor.study.mos import Study
from editor.study.remote import AnswerRejected, WebRater, rater_for_token

DEFAULT_RATE_LIMIT = "300/minute"
MAX_BODY = 4096
_HEADERS = {
    "Cache-Control": "no-store",
    "Referrer-Policy": "no-referrer",  # the token is in the URL
    "X-Content-Type-Options": "nosniff",
    "Content-Security-Policy": "default-src 'self'; img-src 'self'; frame-ancestors 'none'",
}
_STATIC = {"app.js": "text/javascript; charset=utf-8", "app.css": "text/css; charset=utf-8",
           "index.html": "text/html; charset=utf-8"}

Handler = Callable[[Request, WebRater, bytes], Response]


def _error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status, headers=_HEADERS)


class RatingServer:
    """The app's state: the study path, its connection, the web raters' sessions and the rate
    limiter. All store work runs on one thread (``self.pool``, one worker): the connection is
    opened there at startup, each request's store part runs there whole, one after another,
    while the event loop goes on reading and writing HTTP (an answer's commit waits for the
    disk's fsync without holding up other raters' requests)."""

    def __init__(self, study_path: str | Path, rate_limit: str = DEFAULT_RATE_LIMIT) -> None:
        self.path = Path(study_path)
        Study.open(self.path).close()  # a bad file fails here, before anything listens
        self.study: Study | None = None
        self.raters: dict[str, WebRater] = {}
        try:
            self.limit = parse(rate_limit)
        except ValueError:
            raise StudyError(f"rate limit {rate_limit!r} is not like '300/minute'") from None
        self.limiter = MovingWindowRateLimiter(MemoryStorage())
        self.static = {name: (WEB_DIR / name).read_bytes() for name in _STATIC}
        self.pool: ThreadPoolExecutor | None = None

    @asynccontextmanager
    async def lifespan(self, app: Starlette) -> AsyncIterator[None]:
        loop = asyncio.get_running_loop()
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="study-db")
        self.study = await loop.run_in_executor(self.pool, Study.open, self.path)
        try:
            yield
        finally:
            study, self.study, self.raters = self.study, None, {}
            await loop.run_in_executor(self.pool, study.close)
            self.pool.shutdown()

    def _serve(self, handler: Handler, request: Request, body: bytes) -> Response:
        """The store part of a request, on the store thread: token, rate limit, handler."""
        if self.study is None:
            return _error(503, "the study is not open")
        token = str(request.path_params.get("token", ""))
        try:
            rater = rater_for_token(self.study, token)
            if rater is None:
                return _error(403, "this link is not valid (unknown or revoked token)")
            if not self.limiter.hit(self.limit, token):
                return JSONResponse({"error": "too many requests; slow down"}, 429,
                                    headers={**_HEADERS, "Retry-After": "10"})
            if rater not in self.raters:
                self.raters[rater] = WebRater(self.study, rater)
            return handler(request, self.raters[rater], body)
        except AnswerRejected as e:
            return _error(e.status, str(e))
        except StudyError as e:
            return _error(500, str(e))

    def app(self) -> Starlette:
        def guarded(handler: Handler) -> Callable[[Request], Awaitable[Response]]:
            async def endpoint(request: Request) -> Response:
                body = b""
                if request.method == "POST":
                    async for chunk in request.stream():
                        body += chunk
                        if len(body) > MAX_BODY:
                            return _error(413, f"an answer is at most {MAX_BODY} bytes")
                if self.pool is None:
                    return _error(503, "the study is not open")
                return await asyncio.get_running_loop().run_in_executor(
                    self.pool, self._serve, handler, request, body)
            return endpoint

        async def forbidden(request: Request, exc: Exception) -> Response:
            return _error(403, "a rating link with a valid token is needed")

        routes = [
            Route("/r/{token}", guarded(self._slash)),
            Route("/r/{token}/", guarded(self._page)),
            Route("/r/{token}/{name:str}", guarded(self._static)),
            Route("/r/{token}/api/state", guarded(self._state)),
            Route("/r/{token}/api/answer", guarded(self._answer), methods=["POST"]),
            Route("/r/{token}/img/{position:int}", guarded(self._image)),
        ]
        # any URL that is not one of these (so without a token): 403
        return Starlette(routes=routes, lifespan=self.lifespan,
                         exception_handlers={404: forbidden})

    # ------------------------------------------------------------------ endpoints
    def _slash(self, request: Request, rater: WebRater, body: bytes) -> Response:
        # relative, so that it stays right behind a reverse proxy (https, another host name)
        return RedirectResponse(f"{request.path_params['token']}/", 308, headers=_HEADERS)

    def _page(self, request: Request, rater: WebRater, body: bytes) -> Response:
        return Response(self.static["index.html"], headers=_HEADERS,
                        media_type=_STATIC["index.html"])

    def _static(self, request: Request, rater: WebRater, body: bytes) -> Response:
        name = request.path_params["name"]
        if name not in self.static or name == "index.html":
            return _error(404, "no such file")
        return Response(self.static[name], headers=_HEADERS, media_type=_STATIC[name])

    def _state(self, request: Request, rater: WebRater, body: bytes) -> Response:
        return JSONResponse(rater.state(), headers=_HEADERS)

    def _answer(self, request: Request, rater: WebRater, body: bytes) -> Response:
        try:
            data: Any = json.loads(body)
        except (ValueError, UnicodeDecodeError):
            return _error(400, "an answer must be a JSON object")
        return JSONResponse(rater.answer(data), headers=_HEADERS)

    def _image(self, request: Request, rater: WebRater, body: bytes) -> Response:
        data, mime = rater.image(int(request.path_params["position"]))
        return Response(data, media_type=mime,
                        headers={**_HEADERS, "Cache-Control": "private, max-age=3600"})


def create_app(study_path: str | Path, rate_limit: str = DEFAULT_RATE_LIMIT) -> Starlette:
    """The ASGI app serving ``study_path``; :class:`StudyError` if it is not a study."""
    return RatingServer(study_path, rate_limit).app()


def serve(study_path: str | Path, host: str = "127.0.0.1", port: int = 8808,
          rate_limit: str = DEFAULT_RATE_LIMIT,
          ready: Callable[[str], None] | None = None) -> None:
    """Run the app with uvicorn until interrupted (access log off: URLs hold tokens).

    The socket is bound here first, so a busy port or a bad address is a :class:`StudyError`;
    ``ready`` gets the base URL (the real port when ``port`` is 0) before serving starts.
    """
    import uvicorn

    app = create_app(study_path, rate_limit)
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    try:
        sock = socket.create_server((host, port), family=family)
    except OSError as e:
        raise StudyError(f"cannot listen on {host}:{port} ({e.strerror or e})") from None
    # accepted connections inherit it: without it a response's body waits for the ACK of its
    # headers (Nagle + delayed ACK), 40 ms per request on a kept-alive connection
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="on")
    server = uvicorn.Server(config)
    if ready is not None:
        shown = f"[{host}]" if family == socket.AF_INET6 else host
        ready(f"http://{shown}:{sock.getsockname()[1]}")
    with sock:
        server.run(sockets=[sock])


