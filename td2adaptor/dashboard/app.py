"""The dashboard's web application (Starlette): the static page, the fleet as JSON, a robot's TD, live news as
server-sent events, and the two things a page may ask the bus for, a property write and an action operation,
each published on the topic the robot's TD names for it (never one the page names) and refused in read-only
mode. The page is served with a strict content security policy and answers only requests for its own host
(no DNS rebinding) with a JSON body (a form on another site cannot post one without the browser asking first).
"""

from __future__ import annotations

import asyncio
import uuid
from collections.abc import AsyncIterator, Sequence
from pathlib import Path
from typing import Any, Protocol

import orjson
from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from td2adaptor.dashboard.fleet import Fleet
from td2adaptor.dashboard.tdforms import ACTION_OPS, WRITE_OP
from td2adaptor.runtime.bus.bus import BusError

STATIC = Path(__file__).parent / "static"
#: the largest request a page may send (the edge node's default max_event_bytes)
MAX_BODY = 65536
KEEPALIVE = 15.0  # seconds between comments on an idle event stream (proxies close silent ones)
HEADERS = {
    "Content-Security-Policy": "default-src 'self'; img-src 'self' data:; object-src 'none'; frame-ancestors 'none'; "
    "base-uri 'none'; form-action 'self'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}


class Publisher(Protocol):
    def publish(self, topic: str, payload: bytes, *, retain: bool = False, qos: int = 1) -> None: ...


class _Headers:
    """Every response with the security headers above."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        async def send_with(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                names = {name.lower() for name, _ in headers}
                headers += [
                    (k.lower().encode(), v.encode()) for k, v in HEADERS.items() if k.lower().encode() not in names
                ]
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with)


class _Hosts:
    """Only requests for one of `hosts` (the Host header's name, an IPv6 address in brackets too; "*": any): a
    page of another site whose name was pointed at this address (DNS rebinding) is refused."""

    def __init__(self, app: ASGIApp, hosts: Sequence[str]) -> None:
        self.app = app
        self.hosts = frozenset(h.lower() for h in hosts)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and "*" not in self.hosts:
            header = dict(scope.get("headers", [])).get(b"host", b"").decode("latin-1").lower()
            name = header[1:].partition("]")[0] if header.startswith("[") else header.partition(":")[0]
            if name not in self.hosts:
                await PlainTextResponse("Invalid host header", status_code=400)(scope, receive, send)
                return
        await self.app(scope, receive, send)


def _refuse(status: int, words: str) -> JSONResponse:
    return JSONResponse({"error": words}, status_code=status)


def _sse(item: dict[str, Any]) -> bytes:
    return b"data: " + orjson.dumps(item) + b"\n\n"


def create_app(fleet: Fleet, bus: Publisher, *, read_only: bool = False, hosts: Sequence[str] = ("*",)) -> Starlette:
    """The application over `fleet` (fed by the bus elsewhere), publishing with `bus`."""

    async def index(_request: Request) -> Response:
        return FileResponse(STATIC / "index.html")

    async def fleet_json(_request: Request) -> Response:
        return JSONResponse({"robots": fleet.summaries(), "readOnly": read_only})

    async def robot_td(request: Request) -> Response:
        td = fleet.td(request.path_params["robot"])
        if td is None:
            return _refuse(404, "no such robot on the bus")
        return Response(orjson.dumps(td), media_type="application/json")

    async def events(request: Request) -> Response:
        loop = asyncio.get_running_loop()
        ready = asyncio.Event()

        def wake() -> None:
            try:
                loop.call_soon_threadsafe(ready.set)
            except RuntimeError:
                pass  # the server is shutting down

        watcher, snapshot = fleet.watch(request.query_params.get("watch") or None, wake)
        snapshot["readOnly"] = read_only

        async def stream() -> AsyncIterator[bytes]:
            try:
                yield _sse(snapshot)
                while not fleet.closing:
                    try:
                        await asyncio.wait_for(ready.wait(), KEEPALIVE)
                    except asyncio.TimeoutError:
                        yield b": idle\n\n"
                        continue
                    ready.clear()
                    if fleet.closing:
                        return
                    items = watcher.take()
                    if items:
                        yield _sse({"k": "batch", "items": items})
            finally:
                fleet.unwatch(watcher)

        return StreamingResponse(stream(), media_type="text/event-stream", headers={"X-Accel-Buffering": "no"})

    async def body_of(request: Request) -> dict[str, Any] | JSONResponse:
        if read_only:
            return _refuse(403, "the dashboard is read-only: it writes and invokes nothing")
        if request.headers.get("content-type", "").split(";")[0].strip() != "application/json":
            return _refuse(415, "send the request as application/json")
        origin = request.headers.get("origin")
        if origin is not None and origin != f"{request.url.scheme}://{request.url.netloc}":
            return _refuse(403, "requests from another site's page are refused")
        raw = await request.body()
        if len(raw) > MAX_BODY:
            return _refuse(413, f"the request is over {MAX_BODY} bytes")
        try:
            body = orjson.loads(raw)
        except orjson.JSONDecodeError:
            return _refuse(400, "the request is not a JSON document")
        if not isinstance(body, dict):
            return _refuse(400, "the request must be a JSON object")
        return body

    def publish(topic: str, data: Any, answer: dict[str, Any]) -> JSONResponse:
        try:
            bus.publish(topic, orjson.dumps(data))
        except BusError as exc:
            return _refuse(503, f"not sent: {exc}")
        return JSONResponse({"topic": topic, **answer})

    async def action(request: Request) -> Response:
        body = await body_of(request)
        if isinstance(body, JSONResponse):
            return body
        robot, name = request.path_params["robot"], request.path_params["name"]
        op = ACTION_OPS.get(str(body.get("op", "invoke")))
        if op is None:
            return _refuse(400, f"op must be one of {', '.join(ACTION_OPS)}")
        if fleet.td(robot) is None:  # a robot whose node stopped (its TD cleared), or a typo: not "no such form"
            return _refuse(404, "no such robot on the bus")
        topic = fleet.topic_for(robot, name, op)
        if topic is None:
            return _refuse(404, f"the robot's TD names no {op} form of {name!r}")
        data = body.get("input")
        correlation = None
        if isinstance(data, dict):
            correlation = data.setdefault("correlationId", f"dash-{uuid.uuid4().hex[:12]}")
        return publish(topic, {} if data is None else data, {"correlationId": correlation})

    async def write(request: Request) -> Response:
        body = await body_of(request)
        if isinstance(body, JSONResponse):
            return body
        robot, name = request.path_params["robot"], request.path_params["name"]
        if fleet.td(robot) is None:
            return _refuse(404, "no such robot on the bus")
        topic = fleet.topic_for(robot, name, WRITE_OP)
        if topic is None:
            return _refuse(404, f"the robot's TD names no writeproperty form of {name!r}")
        if "value" not in body:
            return _refuse(400, "the request has no value")
        return publish(topic, body["value"], {})

    routes = [
        Route("/", index),
        Route("/api/fleet", fleet_json),
        Route("/api/events", events),
        Route("/api/robots/{robot}/td", robot_td),
        Route("/api/robots/{robot}/actions/{name}", action, methods=["POST"]),
        Route("/api/robots/{robot}/properties/{name}", write, methods=["POST"]),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    middleware = [Middleware(_Headers), Middleware(_Hosts, hosts=list(hosts))]
    return Starlette(routes=routes, middleware=middleware)
