"""The warm-up: compile Anatomesh's numba kernels once (first run), or load them from numba's cache.

numba compiles a kernel the first time a process calls it — minutes of one core for all of
Anatomesh's — and caches the machine code next to the sources (``__pycache__``), where later
processes load it at once. :func:`warm_up` runs the stages on tiny made-up inputs
(the steps of :mod:`.steps`), in the order a first session needs them (reading, extraction, smoothing, report and files first;
decimation, print checks and fixes, scene files after), so that every kernel and every argument
type the default flow uses is compiled and cached before the user's first real run.

Who runs it:

* the command line: ``python -m anatomesh.app.warmup`` compiles everything ahead of time
  (``tools/setup_env.sh`` runs it); and
  every ``anatomesh`` command announces, in one line on stderr, when a run compiles, then
  tells its progress while it goes on compiling (:func:`announce_compiling`);
* the Blender add-on: after the extension is enabled, a background process of Blender's own
  Python runs this module under the add-on's own package name (numba's cache remembers the module
  name a kernel was compiled under), while the UI shows its progress (``addon/warmup.py``).

numba compiles on one core, so a first run shares the compiling among :data:`LANES` processes
(:func:`sharing_kernels`): each runs every step, compiles the kernels it claims first and runs
the others' as plain Python on the tiny inputs (milliseconds); a step is ready when every lane
has passed it, so the first label extraction and all the kernels are ready sooner (figures:
docs/MEASURED.md).

Run as a script it prints one line per step, ``warmup <i>/<n> <step>`` once the steps before it
are ready, then ``warmup done <seconds>`` (the add-on reads them for its progress bar).
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
import threading
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Callable, Dict, List, Optional

from .steps import DEFAULT_STEPS, EXTRA_STEPS, STEPS

#: processes sharing a first run's compiling (:func:`main`)
LANES = max(1, min(2, os.cpu_count() or 1))
#: what a lane prints after each step: ``lane <steps done> <kernels compiled>``
_LANE_LINE = "lane"

#: seconds between two progress lines while a run compiles (:func:`announce_compiling`)
PROGRESS_EVERY = 2.0
#: a one-line note for runs that compile (the CLI prints it on stderr once)
FIRST_RUN_NOTE = ("first run: compiling Anatomesh's kernels once (1-2 min; `python -m anatomesh.app.warmup` "
                  "does it ahead), later runs are fast")


def warm_up(steps: Optional[List[str]] = None,
            progress: Optional[Callable[[float, str], None]] = None) -> Dict[str, float]:
    """Run the warm-up steps (default: all, in :data:`DEFAULT_STEPS` then :data:`EXTRA_STEPS`
    order); returns the seconds each took. ``progress(fraction, text)`` is called before each
    step and at the end (``"done"``)."""
    names = list(steps) if steps is not None else list(DEFAULT_STEPS + EXTRA_STEPS)
    unknown = [n for n in names if n not in STEPS]
    if unknown:
        raise ValueError(f"unknown warm-up step(s) {unknown}; known: {list(STEPS)}")
    seconds: Dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="anatomesh_warmup_") as tmp:
        for i, name in enumerate(names):
            if progress is not None:
                progress(i / len(names), name)
            t0 = time.perf_counter()
            STEPS[name](Path(tmp) / f"step{i}")
            seconds[name] = time.perf_counter() - t0
    if progress is not None:
        progress(1.0, "done")
    return seconds


@contextmanager
def announce_compiling(stream=None, note: str = FIRST_RUN_NOTE,
                       say: Optional[Callable[[str], None]] = None, every: float = PROGRESS_EVERY):
    """Within the block, say ``note`` once on ``stream`` (default stderr), or by calling
    ``say(note)``, when numba starts compiling an Anatomesh kernel, i.e. when the cache is cold
    (a cache hit says nothing); then, while kernels go on compiling, one line at most every
    ``every`` seconds: how many are compiled, for how long, and which one now."""
    def write(text: str) -> None:
        out = stream or sys.stderr
        out.write(f"\n{text}\n" if getattr(out, "isatty", lambda: False)() else f"{text}\n")
        out.flush()

    tell = say or write
    seen = {"count": 0, "start": 0.0, "said": 0.0}

    def on_compile(func, types) -> None:
        now = time.perf_counter()
        if not seen["count"]:
            tell(note)
            seen["start"] = seen["said"] = now
        elif now - seen["said"] >= every:
            tell(f"  compiling kernels: {seen['count']} done in {now - seen['start']:.0f} s, "
                 f"now {func.__module__.rsplit('.', 1)[-1]}.{func.__qualname__}")
            seen["said"] = now
        seen["count"] += 1

    with _on_compile(on_compile):
        yield


@contextmanager
def counting_compiles():
    """Within the block, count the Anatomesh kernels numba compiles (cache misses): yields a
    list that receives each compiled function's qualified name."""
    names: List[str] = []
    with _on_compile(lambda func, types: names.append(f"{func.__module__}.{func.__qualname__}")):
        yield names


@contextmanager
def sharing_kernels(claims: Path):
    """Within the block, share the compiling with the other lanes of a warm-up (processes with
    the same ``claims`` folder): a call of one of our kernels that numba would compile (a cache
    miss) compiles only if this process claims (kernel, argument types) first; else it is loaded
    if numba's cache holds it already, or runs as plain Python (its ``py_func``), and so does
    everything it calls. Kernels compiled inside another kernel's compile are claimed too, so no
    other lane compiles them again."""
    from numba.core.dispatcher import Dispatcher

    original = Dispatcher._compile_for_args
    package = _package()
    state = threading.local()

    def interpreted(func):
        def call(*args, **kws):
            state.depth = getattr(state, "depth", 0) + 1
            try:
                return func(*args, **kws)
            finally:
                state.depth -= 1
        return call

    def as_python(dispatcher, args) -> bool:
        """Called from a kernel run as Python; or another lane compiles it (its claim) and
        numba's cache does not hold it (yet)."""
        if getattr(state, "depth", 0):
            return True
        return not _claim(claims, dispatcher.py_func, _types(dispatcher, args)) \
            and not _in_cache(dispatcher, args)

    def compile_or_interpret(self, *args, **kws):
        if self.py_func.__module__.startswith(package + ".") and as_python(self, args):
            return interpreted(self.py_func)  # numba's dispatcher calls what this returns
        return original(self, *args, **kws)  # compiles, or loads from numba's cache

    Dispatcher._compile_for_args = compile_or_interpret
    try:
        with _on_compile(lambda func, types: _claim(claims, func, types)), _saving_one_at_a_time(claims):
            yield
    finally:
        Dispatcher._compile_for_args = original


@contextmanager
def _saving_one_at_a_time(claims: Path):
    """Within the block, numba saves a compiled kernel into its cache holding a lock shared by
    the lanes: a kernel's index file is read, added to and written back, so two lanes saving
    two argument types of one kernel at once would lose one of them (seen on CI: a second run
    compiling again what the first had compiled)."""
    from numba.core.caching import IndexDataCacheFile

    save = IndexDataCacheFile.save

    def locked_save(self, key, data):
        with _locked(claims / "save.lock"):
            return save(self, key, data)

    IndexDataCacheFile.save = locked_save
    try:
        yield
    finally:
        IndexDataCacheFile.save = save


@contextmanager
def _locked(path: Path):
    """An exclusive lock between processes on the file ``path`` (created if missing)."""
    with open(path, "a+b") as fh:
        if os.name == "nt":
            import msvcrt

            fh.seek(0)
            while True:
                try:
                    msvcrt.locking(fh.fileno(), msvcrt.LK_LOCK, 1)  # itself retries for 10 s
                    break
                except OSError:
                    continue
            try:
                yield
            finally:
                fh.seek(0)
                msvcrt.locking(fh.fileno(), msvcrt.LK_UNLCK, 1)
        else:
            import fcntl

            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)


def _types(dispatcher, args) -> tuple:
    """numba's types of a call's arguments (what it compiles for; omitted defaults included)."""
    return tuple(dispatcher.typeof_pyval(a) for a in args)


def _in_cache(dispatcher, args) -> bool:
    """True when numba's disk cache holds ``dispatcher`` for these arguments (loading it is
    quicker than running a big kernel as Python, on a warm cache)."""
    try:
        return dispatcher._cache.load_overload(_types(dispatcher, args), dispatcher.targetctx) is not None
    except Exception:  # no cache for this kernel, or one numba cannot read: run it as Python
        return False


def _claim(claims: Path, func, types) -> bool:
    """True when this process is the first to claim compiling ``func`` for ``types``."""
    key = f"{func.__module__}.{func.__qualname__}{tuple(str(t) for t in types)}"
    try:
        os.close(os.open(claims / hashlib.sha1(key.encode()).hexdigest(),
                         os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        return True
    except FileExistsError:
        return False


def _package() -> str:
    """Our root package's name (``anatomesh`` or the add-on's ``bl_ext.<repo>.anatomesh``)."""
    return (__package__ or "anatomesh.app.warmup").rsplit(".", 2)[0]  # run as __main__ too


@contextmanager
def _on_compile(callback: Callable):
    """Call ``callback(python_function, argument_types)`` when numba starts compiling one of our
    kernels."""
    from numba.core import event

    package = _package()

    class _Listener(event.Listener):
        def on_start(self, ev):
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            if func is not None and getattr(func, "__module__", "").startswith(package + "."):
                callback(func, ev.data.get("args", ()))

        def on_end(self, ev):
            pass

    listener = _Listener()
    event.register("numba:compile", listener)
    try:
        yield listener
    finally:
        event.unregister("numba:compile", listener)


# -- tiny inputs -----------------------------------------------------------------------------------


# a child process running this module under another root package name (the add-on's
# ``bl_ext.<repo>.anatomesh``): make that package's parents importable, then run it
# (sys.argv: package, folder holding the package, the warm-up's own arguments)
_BOOTSTRAP = """
import runpy, sys, types
package, parent_dir = sys.argv[1], sys.argv[2]
parts = package.split(".")
for i in range(1, len(parts)):
    name = ".".join(parts[:i])
    if name not in sys.modules:
        mod = types.ModuleType(name)
        mod.__path__ = [parent_dir] if i == len(parts) - 1 else []
        sys.modules[name] = mod
sys.argv = [sys.argv[0]] + sys.argv[3:]
runpy.run_module(package + ".app.warmup", run_name="__main__", alter_sys=True)
"""


def command_as(package: str, parent_dir: str, args: Optional[List[str]] = None) -> List[str]:
    """The command line running this warm-up with this Python under the root package name
    ``package`` (e.g. ``bl_ext.<repo>.anatomesh``), imported from ``parent_dir`` (absolute, as
    the kernels will be imported later: numba's cache remembers the module name and path)."""
    return [sys.executable, "-c", _BOOTSTRAP, package, str(parent_dir)] + list(args or [])


def main(argv: Optional[List[str]] = None, program: bool = False) -> int:
    """``python -m anatomesh.app.warmup [--default-only | --steps A,B] [--lanes N] [--quiet]
    [--as PACKAGE FOLDER]``.

    Run as the program (``program``), ``N`` processes (default :data:`LANES`) share the
    compiling: this one and ``N - 1`` copies of its own command line (``--lane``,
    :func:`sharing_kernels`). Prints one
    line per step once every lane has passed the steps before it (``warmup <i>/<n> <step>``),
    after it ``  <seconds> s, <k> kernels compiled``, and at the end ``warmup done <seconds> s,
    <k> kernels compiled`` (0 when every kernel came from numba's cache). ``--as`` runs it
    under another package name (:func:`command_as`; the add-on's tests warm their cache so)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if "--as" in args:
        at = args.index("--as")
        if len(args) < at + 3:
            print("anatomesh warmup: --as needs a package name and its folder, e.g. "
                  "--as bl_ext.user_default.anatomesh ~/.config/blender/5.0/extensions/user_default",
                  file=sys.stderr)
            return 2
        package, folder = args[at + 1:at + 3]
        rest = args[:at] + args[at + 3:]
        return subprocess.run(command_as(package, os.path.abspath(folder), rest)).returncode
    names = list(DEFAULT_STEPS) + ([] if "--default-only" in args else list(EXTRA_STEPS))
    if "--steps" in args:
        names = [n.strip() for n in _option(args, "--steps").split(",") if n.strip()]
    unknown = [n for n in names if n not in STEPS]
    if unknown:
        print(f"anatomesh warmup: unknown step(s) {unknown}; known: {list(STEPS)}", file=sys.stderr)
        return 2
    if "--lane" in args:
        return _other_lane(names, Path(_option(args, "--claims")))
    # the other lanes re-run this program's command line: only when it runs as the program
    lanes = int(_option(args, "--lanes", LANES)) if program else 1
    t0 = time.perf_counter()
    board = _Board(names, max(1, lanes), quiet="--quiet" in args)
    with tempfile.TemporaryDirectory(prefix="anatomesh_lanes_") as claims:
        others = [_start_lane(j, claims, board) for j in range(1, board.lanes)]
        _run_steps(names, Path(claims) if others else None, lambda i, k: board.passed(0, i, k))
        failed = [j for j, (process, reader) in enumerate(others, 1) if _ended(process, reader)]
    for j in failed:
        print(f"anatomesh warmup: lane {j} stopped; its kernels compile on first use", file=sys.stderr)
    lanes_text = f" (by lane: {', '.join(map(str, board.by_lane))})" if others else ""
    print(f"warmup done {time.perf_counter() - t0:.1f} s, {sum(board.by_lane)} kernels compiled"
          f"{lanes_text}", flush=True)
    return 1 if failed else 0


class _Board:
    """Steps passed per lane; prints a step's lines once every lane has passed it."""

    def __init__(self, names: List[str], lanes: int, quiet: bool):
        self.names, self.lanes, self.quiet = names, lanes, quiet
        self.passed_by = [0] * lanes
        self.kernels = [0] * len(names)
        self.by_lane = [0] * lanes
        self.shown = 0
        self.lock = threading.Lock()
        self.t = time.perf_counter()
        self._say(f"warmup 1/{len(names)} {names[0]}" if names else "")

    def passed(self, lane: int, steps: int, kernels: int) -> None:
        """Lane ``lane`` has passed its first ``steps`` steps, compiling ``kernels`` in the last."""
        with self.lock:
            self.passed_by[lane] = steps
            self.kernels[steps - 1] += kernels
            self.by_lane[lane] += kernels
            while self.shown < min(self.passed_by):
                now = time.perf_counter()
                self._say(f"  {now - self.t:.1f} s, {self.kernels[self.shown]} kernels compiled")
                self.shown, self.t = self.shown + 1, now
                if self.shown < len(self.names):
                    self._say(f"warmup {self.shown + 1}/{len(self.names)} {self.names[self.shown]}")

    def _say(self, line: str) -> None:
        if line and not self.quiet:
            print(line, flush=True)


def _start_lane(j: int, claims: str, board: _Board):
    """Lane ``j``: this program's command line again, its lines read into ``board``."""
    command = list(sys.orig_argv) + ["--lane", str(j), "--claims", claims]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stdin=subprocess.PIPE, text=True)

    def read() -> None:
        for line in process.stdout:
            parts = line.split()
            if len(parts) == 3 and parts[0] == _LANE_LINE:
                board.passed(j, int(parts[1]), int(parts[2]))
            elif line.strip():
                print(line.rstrip("\n"), flush=True)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    return process, reader


def _ended(process: subprocess.Popen, reader: threading.Thread) -> bool:
    """Wait for a lane; True when it failed."""
    code = process.wait()
    reader.join()
    process.stdin.close()
    return code != 0


def _other_lane(names: List[str], claims: Path) -> int:
    """A lane started by :func:`main`: every step, sharing the compiling; ``lane <i> <k>`` lines."""
    threading.Thread(target=_exit_with_first_lane, daemon=True).start()
    _run_steps(names, claims, lambda i, k: print(f"{_LANE_LINE} {i} {k}", flush=True))
    return 0


def _run_steps(names: List[str], claims: Optional[Path], passed: Callable[[int, int], None]) -> None:
    """Every step in order, sharing the compiling through ``claims`` (if given); ``passed(i, k)``
    after the i-th step (from 1), which compiled k kernels."""
    with (sharing_kernels(claims) if claims else nullcontext()), counting_compiles() as compiled:
        for i, name in enumerate(names, 1):
            before = len(compiled)
            warm_up([name])
            passed(i, len(compiled) - before)


def _exit_with_first_lane() -> None:
    """The first lane holds our stdin open: its end means the first lane ended (or was ended)."""
    sys.stdin.read()
    os._exit(1)


def _option(args: List[str], name: str, default=None):
    return args[args.index(name) + 1] if name in args else default


if __name__ == "__main__":
    sys.exit(main(program=True))
