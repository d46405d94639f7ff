"""The live view's web server: a Starlette app served by uvicorn.

It attaches to any PLC over Modbus TCP: the soft PLC started with it (``armbench serve
--web``) or one at an address (``armbench web --plc HOST:PORT``). What it shows depends on the
program: the located variables of any program, a trace of those chosen; for the arm
controller also the arm, the plant, mailboxes and commands.

Routes: ``/`` the page (static files shipped in the package), ``/api/info`` the program and
the mode, ``/api/state`` the latest snapshot, ``/api/registers`` the table of located
variables, ``/api/trace`` the trace (GET samples, POST the variables), ``/api/trace.csv`` its
ring as CSV, ``/api/commands`` the command table, ``POST /api/command`` one command, and
``/ws`` a WebSocket that sends each new snapshot as it is polled, with at most
:data:`WS_WINDOW` not yet acknowledged by the page. Commands go to the PLC through
:class:`ArmControllerClient` over Modbus TCP (its own connection and mailbox, the same
handshake as any client); the page never writes a register any other way. One command runs at
a time; bad input is answered 400 with a message and never reaches the PLC.
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import socket
import threading
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import uvicorn
from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..controller_client import ArmControllerClient, HandshakeError
from ..softplc.modbus_client import ModbusError, ModbusIoError, PlcClient
from ..softplc.scan import SoftPlc
from .commands import GROUPS, BadInput, CommandTable, Outcome, run
from .monitor import Monitor, Poller, ProgramMonitor, _finite
from .trace import BadTrace, Trace, parse_since
from .variables import ProgramVariables, controller_variables

STATIC = Path(__file__).resolve().parent / "static"
WS_WINDOW = 8  # snapshots sent and not yet acknowledged by the page


class NotTheController(BadInput):
    """The PLC does not (yet) look like the arm controller: no command is sent to it."""


@dataclass
class Commander:
    """The web server's own controller client (one Modbus connection, one mailbox)."""

    host: str
    port: int
    monitor: Monitor
    table: CommandTable = field(default_factory=CommandTable)
    timeout_s: float = 5.0
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _plc: PlcClient | None = None
    _client: ArmControllerClient | None = None

    def _ensure(self) -> ArmControllerClient:
        if self._client is None:
            self._plc = PlcClient(self.host, self.port, timeout_s=2.0)
            self._plc.connect()
            self._client = ArmControllerClient(self._plc, timeout_s=self.timeout_s,
                                               poll_interval_s=0.001)
            self.table.batch_max = self._client.batch_max
            self.monitor.quiet_sessions.add(self._client.session)  # execute() reports them
        return self._client

    def execute(self, name: object, values: object) -> dict[str, Any]:
        """Check and run one command; the answer for the page. Raises BadInput."""
        answer = self._execute(name, values)
        self.monitor.command_done(answer)
        return answer

    def _execute(self, name: object, values: object) -> dict[str, Any]:
        prepared = self.table.prepare(name, values)
        wrong = self.monitor.waiting
        if wrong is not None:
            # a mailbox write into another program's memory could do anything there
            raise NotTheController(f"{prepared.spec.label}: not sent: {wrong}")
        label = prepared.spec.label
        with self._lock:
            try:
                client = self._ensure()
                t0 = time.perf_counter()
                outcome = run(client, prepared)
                elapsed = time.perf_counter() - t0
            except (HandshakeError, ModbusIoError, ModbusError, OSError) as exc:
                self._drop()
                msg = f"{label}: not sent or not answered: {exc}"
                self.monitor.event("fault", msg)
                return {"ok": False, "result": None, "message": msg}
        name_ = self.monitor.result_name(outcome.result)
        ok = outcome.result == 0
        msg = f"{label}: result {outcome.result} {name_} ({elapsed * 1000:.1f} ms)"
        if prepared.spec.batch and ok:
            failed = sum(1 for b in outcome.batch if b.error_id != 0)
            msg += f"; {len(outcome.batch)} points, {failed} with an error"
        self.monitor.event("info" if ok else "fault", f"web: {msg}")
        return {"ok": ok, "result": outcome.result, "result_name": name_, "message": msg,
                "mailbox": client.mailbox, "batch": _batch_rows(outcome, self.monitor)}

    def _drop(self) -> None:
        if self._plc is not None:
            self._plc.close()
        self._plc = None
        self._client = None

    def close(self) -> None:
        with self._lock:
            if self._client is not None:
                self._client.close()
            self._drop()


def _batch_rows(outcome: Outcome, monitor: Monitor) -> list[dict[str, Any]]:
    return [{"joints": [_finite(a) for a in b.joints_deg],
             "echo": [_finite(a) for a in b.echo_mm],
             "error_id": b.error_id, "error_name": monitor.result_name(b.error_id)}
            for b in outcome.batch]


class _Broadcast:
    """Hands the monitor's snapshots (from its thread) to each WebSocket's queue; a slow page
    gets the newest snapshot, never a backlog."""

    def __init__(self, monitor: Poller) -> None:
        self.monitor = monitor

    @contextlib.asynccontextmanager
    async def listen(self) -> AsyncIterator[asyncio.Queue[str]]:
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[str] = asyncio.Queue(maxsize=1)

        def offer(text: str) -> None:
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(text)

        def from_thread(text: str) -> None:
            loop.call_soon_threadsafe(offer, text)

        unsubscribe = self.monitor.subscribe(from_thread)
        try:
            yield queue
        finally:
            unsubscribe()


def make_app(monitor: Poller, commander: Commander | None, trace: Trace) -> Starlette:
    broadcast = _Broadcast(monitor)
    program = monitor.program

    async def index(request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    async def state(request: Request) -> Response:
        return JSONResponse(monitor.snapshot())

    async def registers(request: Request) -> Response:
        return JSONResponse({"registers": monitor.registers()})

    async def info(request: Request) -> Response:
        return JSONResponse({
            "mode": monitor.mode, "program": program.name,
            "plc_address": f"{monitor.host}:{monitor.port}",
            "local_plc": monitor.local_plc is not None,
            "variables": len(program.registers),
            "unreachable": [u.__dict__ for u in program.unreachable],
            "trace": trace.describe()})

    async def commands(request: Request) -> Response:
        return JSONResponse({"commands": [] if commander is None
                             else commander.table.describe(), "groups": list(GROUPS)})

    async def trace_get(request: Request) -> Response:
        try:
            since = parse_since(request.query_params.get("since"), "since")
            raw = request.query_params.get("config")
            config = None if raw is None else parse_since(raw, "config")
        except BadTrace as exc:
            return JSONResponse({"ok": False, "message": str(exc)}, 400)
        return JSONResponse(trace.samples(since, config))

    async def trace_post(request: Request) -> Response:
        try:
            body = await request.json()
        except ValueError:
            return JSONResponse({"ok": False, "message": "the request must be JSON"}, 400)
        try:
            if not isinstance(body, dict):
                raise BadTrace("the request must be a JSON object {\"variables\": [...]}")
            answer = trace.configure(body.get("variables"))
        except BadTrace as exc:
            return JSONResponse({"ok": False, "message": str(exc)}, 400)
        return JSONResponse({"ok": True, **answer})

    async def trace_csv(request: Request) -> Response:
        return Response(trace.csv(), media_type="text/csv", headers={
            "Content-Disposition": "attachment; filename=\"armbench-trace.csv\""})

    async def command(request: Request) -> Response:
        if commander is None:
            return JSONResponse({"ok": False, "message": f"{program.name} is not the arm "
                                 "controller: the view sends it no commands"}, 400)
        try:
            body = await request.json()
        except ValueError:
            return JSONResponse({"ok": False, "message": "the request must be JSON"}, 400)
        if not isinstance(body, dict):
            return JSONResponse({"ok": False, "message": "the request must be a JSON object "
                                 "{\"name\": ..., \"fields\": {...}}"}, 400)
        try:
            answer = await run_in_threadpool(commander.execute, body.get("name"),
                                             body.get("fields", {}))
        except NotTheController as exc:
            return JSONResponse({"ok": False, "message": str(exc)}, 409)
        except BadInput as exc:
            return JSONResponse({"ok": False, "message": str(exc)}, 400)
        return JSONResponse(answer, 200 if answer["result"] is not None else 503)

    async def ws(websocket: WebSocket) -> None:
        await websocket.accept()
        # At most WS_WINDOW snapshots in flight: the page acknowledges each one it has drawn.
        # Pushing every poll regardless would queue stale snapshots in socket buffers whenever
        # the page is slower than the server; waiting for each acknowledgement would make
        # the update rate one round trip. The queue holds only the newest snapshot.
        credit = asyncio.Semaphore(WS_WINDOW)

        async def acknowledgements() -> None:
            while True:
                await websocket.receive_text()
                credit.release()

        async with broadcast.listen() as queue:
            acks = asyncio.create_task(acknowledgements())
            try:
                while not acks.done():
                    try:
                        await asyncio.wait_for(credit.acquire(), timeout=0.5)
                    except TimeoutError:
                        continue  # look again whether the page is still there
                    await websocket.send_text(await queue.get())
            except (WebSocketDisconnect, RuntimeError):
                return
            finally:
                acks.cancel()

    return Starlette(routes=[
        Route("/", index),
        Route("/api/info", info),
        Route("/api/state", state),
        Route("/api/trace", trace_get),
        Route("/api/trace", trace_post, methods=["POST"]),
        Route("/api/trace.csv", trace_csv),
        Route("/api/registers", registers),
        Route("/api/commands", commands),
        Route("/api/command", command, methods=["POST"]),
        WebSocketRoute("/ws", ws),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ])


def exposure_warning(host: str, port: int) -> str | None:
    """The warning for a live view bound beyond this machine, or None for a loopback one."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if loopback:
        return None
    return (f"the live view on {host}:{port} is reachable from other hosts, and anyone who "
            "reaches it can move the arm (no authentication); bind 127.0.0.1 (the default) "
            "unless the network is isolated and trusted")


class WebView:
    """Monitor + trace (+ commander for the arm controller) + uvicorn on a background thread,
    bound to ``web_host:web_port`` (port 0: any free port; :attr:`port` tells which).
    ``program``: the located variables of what the PLC runs (default: the packaged arm
    controller's map)."""

    def __init__(self, plc_host: str, plc_port: int, *, program: ProgramVariables | None = None,
                 web_host: str = "127.0.0.1", web_port: int = 8080, rate_hz: float = 50.0,
                 trace_period_s: float = 0.001, local_plc: SoftPlc | None = None) -> None:
        program = program or controller_variables()
        self.monitor: Poller
        self.commander: Commander | None = None
        if program.is_controller:
            self.monitor = Monitor(plc_host, plc_port, program, rate_hz=rate_hz,
                                   local_plc=local_plc)
            self.commander = Commander(plc_host, plc_port, self.monitor)
        else:
            # the table is the whole snapshot of another program: refresh it at most 10 Hz
            self.monitor = ProgramMonitor(plc_host, plc_port, program,
                                          rate_hz=min(rate_hz, 10.0), local_plc=local_plc)
        self.trace = Trace(plc_host, plc_port, program, min_period_s=trace_period_s)
        self.app = make_app(self.monitor, self.commander, self.trace)
        self.web_host = web_host
        family = socket.AF_INET6 if ":" in web_host else socket.AF_INET
        self._sock = socket.socket(family, socket.SOCK_STREAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._sock.bind((web_host, web_port))  # bind now: a taken port is an error here
            self._sock.listen(64)
        except OSError:
            self._sock.close()
            raise
        self.port: int = self._sock.getsockname()[1]
        config = uvicorn.Config(self.app, log_level="warning", access_log=False,
                                ws="websockets-sansio", lifespan="off")
        self._server = uvicorn.Server(config)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = f"[{self.web_host}]" if ":" in self.web_host else self.web_host
        return f"http://{host}:{self.port}/"

    def start(self) -> None:
        self.monitor.start()
        self.trace.start()
        self._thread = threading.Thread(target=self._server.run,
                                        kwargs={"sockets": [self._sock]},
                                        name="armbench-web", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + 10.0
        while not self._server.started and time.monotonic() < deadline:
            if not self._thread.is_alive():
                raise RuntimeError("the web server stopped while starting")
            time.sleep(0.01)

    def stop(self) -> None:
        self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None
        self.monitor.stop()
        self.trace.stop()
        if self.commander is not None:
            self.commander.close()
        self._sock.close()

    def __enter__(self) -> WebView:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


MODBUS_PORT = 502  # the Modbus TCP standard port, OpenPLC's default


def parse_plc_address(text: str) -> tuple[str, int]:
    """``HOST:PORT``, ``HOST`` (port 502), ``[IPv6]:PORT`` or ``[IPv6]`` -> (host, port);
    ValueError with the accepted forms otherwise."""
    forms = "give HOST:PORT, e.g. 127.0.0.1:5020 or plc.local:502 ([::1]:502 for IPv6)"
    text = text.strip()
    if text.startswith("["):
        host, sep, rest = text[1:].partition("]")
        if not sep or (rest and not rest.startswith(":")):
            raise ValueError(f"not a PLC address: {text!r}; {forms}")
        port_text = rest[1:] if rest else str(MODBUS_PORT)
    elif text.count(":") == 1:
        host, port_text = text.split(":")
    elif ":" in text:
        raise ValueError(f"not a PLC address: {text!r} (an IPv6 address goes in brackets); "
                         f"{forms}")
    else:
        host, port_text = text, str(MODBUS_PORT)
    if not host:
        raise ValueError(f"not a PLC address: {text!r} has no host; {forms}")
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"not a PLC address: port {port_text!r} of {text!r} is not a "
                         f"number; {forms}") from None
    if not 1 <= port <= 65535:
        raise ValueError(f"not a PLC address: port {port} of {text!r} is not 1..65535")
    return host, port
