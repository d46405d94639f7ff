"""armbench command line: check, build, run, serve.

Exit codes: 0 ok, 1 diagnostics or fault, 2 usage.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from .compiler import CompileFailed, check_files
from .compiler.build import BuildError, build
from .compiler.driver import emit_files, expand
from .faults import PlcFault

if TYPE_CHECKING:  # the soft PLC is imported when a command needs it
    from .softplc.loader import LoadedProgram
    from .softplc.modbus_server import ModbusServer
    from .softplc.scan import SoftPlc

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # argparse exits 2 too; one message style
        self.print_usage(sys.stderr)
        print(f"armbench: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


def _files(paths: Sequence[str]) -> list[Path]:
    files = expand(paths)
    missing = [str(f) for f in files if not f.exists()]
    if missing:
        print(f"armbench: error: no such file: {', '.join(missing)}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)
    if not files:
        print("armbench: error: no .st files given", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)
    return files


def cmd_check(args: argparse.Namespace) -> int:
    diags = check_files(_files(args.files))
    for d in diags:
        print(d.render())
    if diags:
        print(f"{len(diags)} error(s)", file=sys.stderr)
        return EXIT_FAIL
    return EXIT_OK


def cmd_build(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    _, unit = emit_files(_files(args.files))
    lib = build(unit)
    dt = time.perf_counter() - t0
    print(f"{lib.path} ({'cached' if lib.cached else 'built'} in {dt:.3f} s; C: {lib.c_path})")
    return EXIT_OK


def cmd_run(args: argparse.Namespace) -> int:
    from .softplc.loader import load_program
    from .softplc.scan import PlcState, SoftPlc

    prog = load_program(_files(args.files))
    plc = SoftPlc(prog)
    plc.run()
    base = min(t.interval_ns for t in prog.tasks)
    now = 0
    scans = 0
    while scans < args.cycles and plc.state is PlcState.RUNNING:
        plc.step(now)
        now += base
        scans += 1
    status = 0
    if plc.state is PlcState.FAULT and plc.fault is not None:
        print(f"{plc.fault.location}: PLC fault: {plc.fault.message}", file=sys.stderr)
        status = EXIT_FAIL
    if args.dump:
        dump = {name: prog.instance_vars(name) for name in prog.instance_names()}
        print(json.dumps(_finite(dump), indent=2))
    else:
        print(f"ran {scans} cycle(s) of {base / 1e6:g} ms; state {plc.state.name}")
    return status


def _finite(o: object) -> object:
    """Strict JSON has no NaN/Infinity: write those as the strings "nan", "inf", "-inf"."""
    if isinstance(o, float) and not math.isfinite(o):
        return repr(o)
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, list):
        return [_finite(v) for v in o]
    return o


def cmd_serve(args: argparse.Namespace) -> int:
    from .softplc.loader import load_program
    from .softplc.modbus_server import DEFAULT_IDLE_TIMEOUT_S, DEFAULT_MAX_CLIENTS, ModbusServer
    from .softplc.scan import SoftPlc

    prog = load_program(_files(args.files))
    plc = SoftPlc(prog)
    server = ModbusServer(
        prog.image, plc.lock, host=args.host, port=args.port,
        max_clients=DEFAULT_MAX_CLIENTS if args.max_clients is None else args.max_clients,
        idle_timeout_s=DEFAULT_IDLE_TIMEOUT_S if args.idle_timeout is None else args.idle_timeout)
    # The server's warnings (non-loopback address, failed requests) as one stderr line each;
    # without a handler only Python's bare last-resort output would show them.
    to_stderr = logging.StreamHandler(sys.stderr)
    to_stderr.setFormatter(logging.Formatter("armbench: %(levelname)s: %(message)s"))
    server_log = logging.getLogger(ModbusServer.__module__)
    server_log.addHandler(to_stderr)
    try:
        return _serve(args, prog, plc, server)
    finally:
        server_log.removeHandler(to_stderr)


def _serve(args: argparse.Namespace, prog: LoadedProgram, plc: SoftPlc,
           server: ModbusServer) -> int:
    try:
        server.start()
    except OSError as exc:
        print(f"armbench: error: cannot listen on {args.host}:{args.port}: {exc.strerror}",
              file=sys.stderr)
        return EXIT_FAIL
    plc.run()
    plc.start()
    print(f"serving Modbus TCP on {args.host}:{server.port}; tasks: "
          + ", ".join(f"{t.name} every {t.interval_ns / 1e6:g} ms" for t in prog.tasks),
          flush=True)
    deadline = None if args.duration is None else time.monotonic() + args.duration
    reported = False
    try:
        while deadline is None or time.monotonic() < deadline:
            time.sleep(0.2)
            if plc.fault is not None and not reported:
                reported = True
                print(f"{plc.fault.location}: PLC fault: {plc.fault.message} (outputs held; "
                      "Modbus keeps answering)", file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        plc.stop()
        server.stop()
    return EXIT_FAIL if plc.fault is not None else EXIT_OK


def cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_from_args

    return run_from_args(args)


def cmd_export(args: argparse.Namespace) -> int:
    from .export import OUT_DIR, generate

    exp = generate(_files(args.files) if args.files else None)
    out = Path(args.out) if args.out is not None else OUT_DIR
    if args.check:
        stale = exp.stale(out)
        for path, why in stale:
            print(f"stale: {path} ({why}); regenerate with `armbench export`")
        return EXIT_FAIL if stale else EXIT_OK
    for path in exp.write(out):
        print(f"wrote {path}")
    return EXIT_OK


def make_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="armbench", description="ST compiler, soft PLC and test bench for the "
                "arm-kinematics library")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    c = sub.add_parser("check", help="portability and type check (exit 1 on error)")
    c.add_argument("files", nargs="+", help=".st files or folders")
    c.set_defaults(func=cmd_check)
    b = sub.add_parser("build", help="compile to a cached shared library")
    b.add_argument("files", nargs="+")
    b.set_defaults(func=cmd_build)
    r = sub.add_parser("run", help="run the CONFIGURATION headless")
    r.add_argument("files", nargs="+")
    r.add_argument("--cycles", type=int, default=1, help="scans of the fastest task")
    r.add_argument("--dump", action="store_true", help="print program variables as JSON")
    r.set_defaults(func=cmd_run)
    s = sub.add_parser("serve", help="run in real time and serve Modbus TCP")
    s.add_argument("files", nargs="+")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=5020)
    s.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    s.add_argument("--idle-timeout", type=float, default=None, metavar="S",
                   help="close a Modbus connection that sends no request for S seconds "
                   "(default 300; 0: never)")
    s.add_argument("--max-clients", type=int, default=None, metavar="N",
                   help="Modbus connections open at once; when full, a new client replaces "
                   "the connection idle longest (default 64)")
    s.set_defaults(func=cmd_serve)
    x = sub.add_parser("export", help="write the OpenPLC upload .st and PLCopen XML "
                       "(default: st/*.st + plc_project/Controller.st -> plc_project/)")
    x.add_argument("files", nargs="*", help=".st files or folders (default: the project)")
    x.add_argument("--out", default=None, help="output folder (default: plc_project/)")
    x.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 when the files in the output folder are stale")
    x.set_defaults(func=cmd_export)
    d = sub.add_parser("demo", help="drive the 360-point circle over Modbus through the "
                       "controller, PCA9685 and servo models")
    from .demo import add_arguments
    add_arguments(d)
    d.set_defaults(func=cmd_demo)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = make_parser().parse_args(argv)
    try:
        rc: int = args.func(args)
        return rc
    except CompileFailed as exc:
        print(str(exc))
        return EXIT_FAIL
    except (BuildError, ValueError, KeyError) as exc:
        print(f"armbench: error: {exc}", file=sys.stderr)
        return EXIT_FAIL
    except PlcFault as exc:
        print(str(exc), file=sys.stderr)
        return EXIT_FAIL
    except Exception as exc:  # a bench bug must still not greet the user with a traceback
        print(f"armbench: internal error ({type(exc).__name__}: {exc}); please report it "
              "with the command and the ST files", file=sys.stderr)
        return EXIT_FAIL


if __name__ == "__main__":
    sys.exit(main())
