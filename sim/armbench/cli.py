"""armbench command line: check, build, run, serve, web, export, demo, demo-imu.

Programs are compiled with what they use of the armbench ST library (armbench.locate,
armbench.compiler.uses) unless --no-library.
Exit codes: 0 ok, 1 diagnostics or fault, 2 usage (one line on stderr).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from . import argtypes
from .compiler import CompileFailed
from .compiler.build import BuildError, build
from .compiler.diagnostics import Diagnostic, Diagnostics
from .compiler.driver import Analysis, analyse_program, expand
from .compiler.emit_c import emit
from .compiler.symbols import CheckedProgram
from .compiler.targets import CODESYS_ONLY, SOFT_PLC, TARGET_NAMES, Target
from .compiler.uses import Library
from .demo_options import add_demo_arguments, add_follow_arguments
from .faults import PlcFault
from .locate import (
    LibrarySelection,
    LocateError,
    NotACheckout,
    default_project,
    find_checkout,
    select_library,
)

if TYPE_CHECKING:  # the soft PLC is imported when a command needs it
    from .compiler.ffi import Module
    from .softplc.loader import LoadedProgram
    from .softplc.modbus_server import ModbusServer
    from .softplc.scan import SoftPlc
    from .web.app import WebView
    from .web.variables import ProgramVariables

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2


class UsageError(Exception):
    """Bad command line: one line on stderr, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        # argparse prints the whole usage block; one line naming the command is enough
        raise UsageError(f"{self.prog}: error: {message} (see {self.prog} --help)")


def _given(paths: Sequence[str]) -> list[Path]:
    files = expand(paths)
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise UsageError(f"armbench: error: no such file: {', '.join(missing)}")
    if not files:
        raise UsageError(f"armbench: error: no .st files in {', '.join(paths)}")
    return files


def _library_files() -> list[Path]:
    """Where a program's names are looked up: the armbench ST library and the controller's
    blocks (plc_project/controller/*.st), taken by use."""
    project = default_project()
    return [*project.library(), *project.components()]


def _select(args: argparse.Namespace) -> LibrarySelection:
    """The given files, and the library files they do not replace (none with --no-library)."""
    return select_library(_given(args.files), not args.no_library)


def _analyse(args: argparse.Namespace, target: Target = SOFT_PLC
             ) -> tuple[LibrarySelection, Analysis]:
    """The given files checked with what they use of the library, for ``target`` (build, run
    and serve compile what OpenPLC runs, for the soft PLC: what only OpenPLC's upload refuses,
    the names Config0 and Res0, is a warning there); a note (stderr) names the program's
    declarations that library declarations it uses get instead of their own."""
    selection = _select(args)
    analysis = analyse_program(selection.given, selection.library, target)
    note = analysis.library.note()
    if note is not None and analysis.program is not None:  # else E0213 says it
        print(f"armbench: note: {note}", file=sys.stderr)
    return selection, analysis


def _checked(args: argparse.Namespace) -> CheckedProgram:
    """The program compiled for the soft PLC; its warnings on stderr, one line each."""
    _, analysis = _analyse(args)
    if analysis.program is None:
        raise CompileFailed(analysis.diagnostics.sorted())
    for d in analysis.diagnostics.sorted():
        if d.severity == "warning":
            print(d.render(), file=sys.stderr)
    return analysis.program


def _module(args: argparse.Namespace) -> Module:
    return _module_of(_checked(args))


def _module_of(prog: CheckedProgram) -> Module:
    from .compiler.ffi import Module

    unit = emit(prog)
    return Module(prog, build(unit), unit.decls)


_NOT_STANDARD = re.compile(r"^(\w+) is not an IEC standard function")


def _library_hint(diags: Sequence[Diagnostic]) -> str | None:
    """With --no-library: which library files declare the names the program misses."""
    unknown = {m.upper() for d in diags if d.code in ("E0200", "E0400")
               for m in [*re.findall(r"'(\w+)'", d.message), *_NOT_STANDARD.findall(d.message)]}
    lib = Library(_library_files(), Diagnostics())
    declaring = {lib.file_of(n) for n in unknown}
    files = [Path(f).name for f in lib.order if f in declaring]  # in library order
    if not files:
        return None
    return (f"armbench: note: unknown names are declared in the armbench library "
            f"({', '.join(files)}): drop --no-library, or pass those files too")


def cmd_check(args: argparse.Namespace) -> int:
    target = Target.named(args.target)
    if args.files:
        selection, analysis = _analyse(args, target)
        files, library = selection.given, len(analysis.library.files)
    else:  # the library and the controller the tools use
        files, library = default_project().sources(), -1
        analysis = analyse_program(files, target=target)
    prog, diags = analysis.program, analysis.diagnostics
    items = diags.sorted()
    for d in items:
        print(d.render())
    errors = sum(d.severity == "error" for d in items)
    warnings = sum(d.severity == "warning" for d in items)
    notes = len(items) - errors - warnings
    n_files = len(files) + max(library, 0)
    what = f"{n_files} file{'s' if n_files != 1 else ''}"
    if library > 0:
        what += f" ({library} from the armbench library)"
    elif library < 0:
        what += " (the armbench library and plc_project/Controller.st)"
    if prog is not None:
        what += f", {len(prog.pous)} POU{'s' if len(prog.pous) != 1 else ''}"
    summary = f"checked {what}: {errors} error{'s' if errors != 1 else ''}"
    if warnings:
        summary += f", {warnings} warning{'s' if warnings != 1 else ''}"
    if notes:
        summary += f", {notes} note{'s' if notes != 1 else ''}"
    print(summary, file=sys.stderr)
    if errors and args.no_library:
        hint = _library_hint(items)
        if hint:
            print(hint, file=sys.stderr)
    return EXIT_FAIL if errors else EXIT_OK


def cmd_build(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    unit = emit(_checked(args))
    lib = build(unit)
    dt = time.perf_counter() - t0
    how = "cached" if lib.cached else "built" if lib.units == 1 else \
        f"built as {lib.units} translation units"
    print(f"{lib.path} ({how} in {dt:.3f} s; C: {lib.c_path})")
    return EXIT_OK


def cmd_run(args: argparse.Namespace) -> int:
    from .softplc.loader import LoadedProgram
    from .softplc.scan import PlcState, SoftPlc

    prog = LoadedProgram(_module(args))
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
    from .softplc.loader import LoadedProgram, load_program
    from .softplc.modbus_server import DEFAULT_IDLE_TIMEOUT_S, DEFAULT_MAX_CLIENTS, ModbusServer
    from .softplc.openplc_v4 import V4Settings
    from .softplc.serving import soft_plc

    if args.web and args.flavor == "codesys":
        print("armbench: error: --web: the live view speaks OpenPLC's register map only; "
              "leave out --flavor codesys to use it", file=sys.stderr)
        return EXIT_USAGE
    if args.v4_counts is not None and args.flavor != "openplc-v4":
        print("armbench: error: --v4-counts: only with --flavor openplc-v4", file=sys.stderr)
        return EXIT_USAGE
    # Without files: the armbench library and the controller.
    checked = _checked(args) if args.files else None
    prog = LoadedProgram(_module_of(checked)) if checked is not None else \
        load_program(default_project().sources())
    try:
        v4 = None if args.flavor != "openplc-v4" else V4Settings(args.v4_counts)
        plc, server = soft_plc(
            prog, args.flavor, v4=v4, host=args.host, port=args.port,
            max_clients=DEFAULT_MAX_CLIENTS if args.max_clients is None else args.max_clients,
            idle_timeout_s=DEFAULT_IDLE_TIMEOUT_S if args.idle_timeout is None
            else args.idle_timeout)
    except ValueError as exc:  # a variable the CODESYS layout or v4's counts cannot serve
        print(f"armbench: error: --flavor {args.flavor}: {exc}", file=sys.stderr)
        return EXIT_FAIL
    # The server's warnings (non-loopback address, failed requests, in the server or the
    # CODESYS device) as one stderr line each; without a handler only Python's bare
    # last-resort output would show them.
    to_stderr = logging.StreamHandler(sys.stderr)
    to_stderr.setFormatter(logging.Formatter("armbench: %(levelname)s: %(message)s"))
    server_log = logging.getLogger(ModbusServer.__module__.rpartition(".")[0])
    server_log.addHandler(to_stderr)
    try:
        return _serve(args, prog, plc, server, checked)
    finally:
        server_log.removeHandler(to_stderr)


def _v4_layout(server: ModbusServer) -> str:
    """The segments an OpenPLC v4 flavored server exposes, for the serve line."""
    seg = getattr(server.device, "segments", None)
    if seg is None:
        return ""
    return (f", answering as OpenPLC v4's Modbus plugin (holding registers 0..."
            f"{seg.holding_registers - 1}: %QW {seg.qw_count}, %MW {seg.mw_count}, %MD "
            f"{seg.md_count}, %ML {seg.ml_count}; coils {seg.coils}, discrete inputs "
            f"{seg.ix_bits}, input registers {seg.iw_count}; exception 02 past them)")


def _serve(args: argparse.Namespace, prog: LoadedProgram, plc: SoftPlc,
           server: ModbusServer, checked: CheckedProgram | None) -> int:
    try:
        server.start()
    except OSError as exc:
        print(f"armbench: error: cannot listen on {args.host}:{args.port}: {exc.strerror}",
              file=sys.stderr)
        return EXIT_FAIL
    plc.run()
    plc.start()
    layout = "" if server.device is None else \
        ", the CODESYS variant's register layout (plc_project/codesys/register-map.md)" \
        if args.flavor == "codesys" else _v4_layout(server)
    print(f"serving Modbus TCP on {args.host}:{server.port}{layout}; tasks: "
          + ", ".join(f"{t.name} every {t.interval_ns / 1e6:g} ms" for t in prog.tasks),
          flush=True)
    web = None
    if args.web:
        web = _start_web(args, plc, server, _web_program(args, checked))
        if web is None:
            plc.stop()
            server.stop()
            return EXIT_FAIL
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
        if web is not None:
            web.stop()
        plc.stop()
        server.stop()
    return EXIT_FAIL if plc.fault is not None else EXIT_OK


def _web_program(args: argparse.Namespace, checked: CheckedProgram | None) -> ProgramVariables:
    """The located variables the live view shows: of the program checked from the given files
    (with what it uses of the library), or the packaged controller's map."""
    from .web.variables import controller_variables, program_variables

    if checked is None:
        return controller_variables()
    return program_variables(checked, ", ".join(Path(f).name for f in _given(args.files)))


def _start_web(args: argparse.Namespace, plc: SoftPlc | None, server: ModbusServer | None,
               program: ProgramVariables, plc_address: tuple[str, int] | None = None
               ) -> WebView | None:
    """The live view, a Modbus client of the server just started or of the PLC at
    ``plc_address`` (None: could not listen)."""
    from .web.app import WebView, exposure_warning

    if plc_address is not None:
        plc_host, plc_port = plc_address
    else:
        assert server is not None
        # The view talks to the PLC like any client: over Modbus, on the loopback when the
        # server listens on every address.
        plc_host = "127.0.0.1" if args.host in ("0.0.0.0", "") else "::1" \
            if args.host == "::" else args.host
        plc_port = server.port
    try:
        web = WebView(plc_host, plc_port, program=program, web_host=args.web_host,
                      web_port=args.web_port, rate_hz=args.web_rate,
                      trace_period_s=args.trace_period / 1e3, local_plc=plc)
    except OSError as exc:
        print(f"armbench: error: cannot listen on {args.web_host}:{args.web_port} for the "
              f"web view: {exc.strerror}", file=sys.stderr)
        return None
    warning = exposure_warning(args.web_host, web.port)
    if warning is not None:
        print(f"armbench: warning: {warning}", file=sys.stderr)
    web.start()
    what = "the arm controller" if program.is_controller else \
        f"{program.name}, {len(program.registers)} located variables"
    print(f"live view on {web.url} (updates at {web.monitor.rate_hz:g} Hz) of "
          f"{plc_host}:{plc_port}: {what}", flush=True)
    return web


def cmd_web(args: argparse.Namespace) -> int:
    """The live view of a PLC that runs elsewhere (a soft PLC, OpenPLC), over Modbus."""
    program = _web_program(args, _checked(args) if args.files else None)
    web = _start_web(args, None, None, program, args.plc)
    if web is None:
        return EXIT_FAIL
    deadline = None if args.duration is None else time.monotonic() + args.duration
    try:
        while deadline is None or time.monotonic() < deadline:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        web.stop()
    return EXIT_OK


def _plc_address(text: str) -> tuple[str, int]:
    from .web.app import parse_plc_address

    try:
        return parse_plc_address(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _web_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--web-host", default="127.0.0.1", help="address of the live view "
                   "(127.0.0.1)")
    p.add_argument("--web-port", type=argtypes.port, default=8080,
                   help="port of the live view, 0..65535 (8080; 0: any)")
    p.add_argument("--web-rate", type=argtypes.update_rate, default=50.0, metavar="HZ",
                   help="updates per second of the live view, 1..1000 (50; 10 at most for "
                   "a program other than the arm controller)")
    p.add_argument("--trace-period", type=argtypes.float_between(0.0, 10000.0, "ms"),
                   default=1.0, metavar="MS", help="shortest time between two trace "
                   "samples, 0..10000 ms (1: as fast as the PLC answers, at most 1000 "
                   "samples/s; give the PLC's scan time to spare a busy PLC)")


def cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_from_args

    return run_from_args(args)


def cmd_demo_imu(args: argparse.Namespace) -> int:
    from .follow_demo import run_from_args as run_follow_demo

    return run_follow_demo(args)


def cmd_export(args: argparse.Namespace) -> int:
    from .export import generate, generate_library

    if args.regenerate:  # the project's own exports, from the checkout's own sources
        if (args.files or args.out is not None or args.no_library or args.name
                or args.library_only):
            raise UsageError("armbench export: error: --regenerate rewrites the checkout's "
                             "plc_project/ from its st/ and Controller.st: give no files, "
                             "--out, --name, --library-only or --no-library with it")
        project = find_checkout(args.repo)
        exp = generate(None, project)
        out = project.plc_project
    else:
        if args.out is None:
            raise UsageError("armbench export: error: give --out DIR for the exported files "
                             "(the repository's own plc_project/ is rewritten only by "
                             "`armbench export --regenerate` in a checkout)")
        if args.repo is not None:
            raise UsageError("armbench export: error: --repo goes with --regenerate")
        if args.library_only and not args.files:
            exp = generate_library(name=args.name)
        elif args.files:
            selection = _select(args)
            make = generate_library if args.library_only else generate
            exp = make(selection.given, library=selection.library, name=args.name)
        else:
            exp = generate(name=args.name)
        out = Path(args.out)
    for warning in exp.warnings:
        print(f"armbench export: warning: {warning}", file=sys.stderr)
    if args.check:
        stale = exp.stale(out)
        for path, why in stale:
            print(f"stale: {path} ({why}); regenerate with `armbench export "
                  + ("--regenerate`" if args.regenerate else f"--out {args.out}`"))
        return EXIT_FAIL if stale else EXIT_OK
    for path in exp.write(out):
        print(f"wrote {path}")
    if args.files and not args.regenerate:
        _warn_codesys_refusals(args)
    return EXIT_OK


def _warn_codesys_refusals(args: argparse.Namespace) -> None:
    """The export checked the files for OpenPLC; its CODESYS XML holds the same text, so say
    (without failing the export) what a CODESYS-family compiler would refuse in it."""
    selection = _select(args)
    refused = [d for d in analyse_program(selection.given, selection.library,
                                          CODESYS_ONLY).diagnostics.sorted()
               if d.severity == "error"]
    for d in refused:
        print(f"armbench export: warning: CODESYS refuses this: {d.render()}", file=sys.stderr)
    if refused:
        print(f"armbench export: warning: the OpenPLC upload is fine; the CODESYS variant needs "
              f"the {len(refused)} change{'s' if len(refused) != 1 else ''} above "
              f"(`armbench check --target codesys`, docs/diagnostics.md)", file=sys.stderr)


def _library_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--no-library", action="store_true",
                   help="do not look names up in the armbench ST library (default: the TYPEs "
                   "and POUs of it that your files use are added, unless your files declare "
                   "them)")


def make_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="armbench", description="ST compiler, soft PLC and test bench for the "
                "arm-kinematics library. Programs are compiled together with what they use of "
                "the armbench ST library (st/*.st, shipped with the package) unless "
                "--no-library.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    c = sub.add_parser("check", help="portability and type check (exit 1 on error)")
    c.add_argument("files", nargs="*", help=".st files or folders (default: the armbench "
                   "library and plc_project/Controller.st)")
    _library_option(c)
    c.add_argument("--target", choices=TARGET_NAMES, default="all",
                   help="the dialects to check for: openplc (OpenPLC v3's MatIEC and its "
                   "upload, which needs CONFIGURATION Config0 and RESOURCE Res0), openplc-v4 "
                   "(OpenPLC v4's STruC++), codesys (IEC 61131-3 3rd edition, CODESYS, "
                   "TwinCAT, RuSTy) or all (default); what only the others refuse is a "
                   "warning. build, run and serve compile for the soft PLC: openplc's rules, "
                   "with the upload's names a warning")
    c.set_defaults(func=cmd_check)
    b = sub.add_parser("build", help="compile to a cached shared library")
    b.add_argument("files", nargs="+")
    _library_option(b)
    b.set_defaults(func=cmd_build)
    r = sub.add_parser("run", help="run the CONFIGURATION headless")
    r.add_argument("files", nargs="+")
    _library_option(r)
    r.add_argument("--cycles", type=argtypes.count, default=1,
                   help="scans of the fastest task (1)")
    r.add_argument("--dump", action="store_true", help="print program variables as JSON")
    r.set_defaults(func=cmd_run)
    s = sub.add_parser("serve", help="run in real time and serve Modbus TCP (--web: and the "
                       "live view in a browser)")
    s.add_argument("files", nargs="*", help=".st files or folders (default: the armbench "
                   "library and plc_project/Controller.st)")
    _library_option(s)
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=argtypes.port, default=5020, help="0..65535 (5020; 0: any)")
    s.add_argument("--duration", type=argtypes.seconds, default=None,
                   help="stop after S seconds")
    s.add_argument("--idle-timeout", type=argtypes.seconds, default=None, metavar="S",
                   help="close a Modbus connection that sends no request for S seconds "
                   "(default 300; 0: never)")
    s.add_argument("--max-clients", type=argtypes.positive_count, default=None, metavar="N",
                   help="Modbus connections open at once; when full, a new client replaces "
                   "the connection idle longest (default 64)")
    s.add_argument("--flavor", "--plc-flavor", dest="flavor",
                   choices=("openplc", "openplc-v4", "codesys"), default="openplc",
                   help="the Modbus server served: OpenPLC v3's (default); OpenPLC v4's "
                        "Modbus plugin (v3's map, each segment sized to the program, "
                        "exception 02 outside, writes applied at the next scan: "
                        "docs/modbus-parity.md); or the CODESYS variant's layout, as "
                        "`armbench export` lays the program out for a CODESYS Modbus TCP "
                        "Server Device")
    s.add_argument("--v4-counts", type=argtypes.v4_counts, default=None,
                   metavar="KEY=N[,KEY=N...]",
                   help="with --flavor openplc-v4: the Modbus server counts set in v4's "
                        "editor (qw_count, mw_count, md_count, ml_count, qx_bits, ix_bits, "
                        "iw_count); default: those that keep every variable at its v3 "
                        "address (for the controller qw_count=1024,mw_count=1024)")
    s.add_argument("--web", action="store_true",
                   help="also serve the live view over HTTP (the program's located variables "
                   "and a trace; for the arm controller the arm in 3-D and its commands); it "
                   "is a Modbus client of this PLC")
    _web_options(s)
    s.set_defaults(func=cmd_serve)
    w = sub.add_parser("web", help="the live view of a PLC at an address (soft PLC, OpenPLC): "
                       "located variables, trace, and for the arm controller the arm and its "
                       "commands")
    w.add_argument("--plc", type=_plc_address, required=True, metavar="HOST:PORT",
                   help="the PLC's Modbus TCP address (port 502 when left out)")
    w.add_argument("--program", dest="files", nargs="+", action="extend", default=[],
                   metavar="FILE", help=".st files or folders of the program the PLC runs "
                   "(default: the armbench arm controller); compiled with the armbench "
                   "library unless --no-library, as for `armbench serve`")
    _library_option(w)
    _web_options(w)
    w.add_argument("--duration", type=argtypes.seconds, default=None,
                   help="stop after S seconds")
    w.set_defaults(func=cmd_web)
    x = sub.add_parser("export", help="write the OpenPLC upload .st and PLCopen XML of a "
                       "program (with the library) into --out, or regenerate the "
                       "repository's own plc_project/ exports")
    x.add_argument("files", nargs="*", help=".st files or folders (default: the armbench "
                   "library and plc_project/Controller.st)")
    _library_option(x)
    x.add_argument("--out", default=None, help="output folder")
    x.add_argument("--name", default=None,
                   help="name of the exported files (default: the program's PROGRAM, else "
                   "its first file; the arm controller: arm_controller)")
    x.add_argument("--library-only", action="store_true",
                   help="blocks and types alone, no PROGRAM or CONFIGURATION, as PLCopen XML "
                   "for CODESYS (codesys/NAME.xml): the given files, default the armbench "
                   "library (armbench_library)")
    x.add_argument("--regenerate", action="store_true",
                   help="rewrite the checkout's plc_project/ exports from its st/*.st and "
                   "plc_project/Controller.st")
    x.add_argument("--repo", default=None,
                   help="the checkout for --regenerate (default: found from the current "
                   "directory)")
    x.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 when the files in the output folder are stale")
    x.set_defaults(func=cmd_export)
    d = sub.add_parser("demo", help="drive the 360-point circle over Modbus through the "
                       "controller, PCA9685 and servo models")
    add_demo_arguments(d)
    d.set_defaults(func=cmd_demo)
    di = sub.add_parser("demo-imu", help="the simulated hand's IMU drives the 5-axis arm's "
                        "tool over Modbus (FollowImu), in simulated time")
    add_follow_arguments(di)
    di.set_defaults(func=cmd_demo_imu)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args: argparse.Namespace | None = None
    try:
        args = make_parser().parse_args(argv)
        rc: int = args.func(args)
        return rc
    except (UsageError, NotACheckout) as exc:
        msg = str(exc)
        print(msg if msg.startswith("armbench") else f"armbench: error: {msg}",
              file=sys.stderr)
        return EXIT_USAGE
    except CompileFailed as exc:
        print(str(exc))
        if args is not None and getattr(args, "no_library", False):
            hint = _library_hint(exc.diagnostics)
            if hint:
                print(hint, file=sys.stderr)
        return EXIT_FAIL
    except (BuildError, LocateError, ValueError, KeyError) as exc:
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
