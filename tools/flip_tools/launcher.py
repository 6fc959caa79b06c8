"""A small stand-in for `ros2 launch` on top of subprocess + rclpy.

- Launcher.start(): every node is its own OS process (own session/process group, own env with an
  isolated ROS_DOMAIN_ID on loopback), stdout+stderr to a log file, PR_SET_PDEATHSIG so a node
  dies with its launcher even if the launcher is SIGKILLed.
- GraphWatcher: readiness through the ROS graph (node names, services, publisher/subscriber
  counts), never through sleeps; fails fast if a watched process exits meanwhile.
- Launcher.stop()/stop_all(): SIGINT, then SIGTERM, then SIGKILL, to the whole process group;
  reports how each process ended; nothing is left behind (checked by `leftovers()`).
- An optional process (`start(..., optional=True)`: the live view) is stopped and reported like the
  others, but its exit does not fail `check_alive()`: the graph does not need it.
- Every process of one graph gets the same FLIP_LOCKSTEP_CPU (one of this process's CPUs, chosen
  by the domain id so that graphs running side by side spread over the CPUs): the simulator and
  its controller pin themselves to it (flip_transport.lockstep). An environment that sets
  FLIP_LOCKSTEP_CPU (empty: no pinning) overrides it.
- Interrupts: `interrupt_latch` turns SIGINT/SIGTERM into `Interrupted` and remembers it; every
  wait loop here re-raises a remembered one, because a signal handler's exception is lost when it
  fires inside a `__del__` or a weakref callback (Python only prints "Exception ignored in ...").
- Every process gets FASTDDS_PROFILE as its Fast DDS default profile (FASTRTPS_DEFAULT_PROFILES_FILE,
  unless the environment names one): shared-memory queues deep enough that a best-effort reader
  stalled for seconds (the recorder on a loaded machine) loses nothing of a 2 kHz lockstep (the
  default 512-message port queue overflowed after ~130 steps), and UDP (discovery) on loopback.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Sequence

from .fastdds import FASTDDS_PROFILE, PROFILES_ENV, fastdds_profile_file  # noqa: F401
from .rosenv import node_env

_PR_SET_PDEATHSIG = 1
LOCKSTEP_CPU_ENV = "FLIP_LOCKSTEP_CPU"      # read by flip_transport.lockstep.pin_to_lockstep_cpu
LOCKSTEP_SCHED_ENV = "FLIP_LOCKSTEP_SCHED"  # the same function's scheduling policy ('batch', 'other')


def _child_setup(nice: int = 0):  # runs in the child between fork and exec
    # SIGINT as the stop sequence expects it: a launcher started in the background by a
    # non-interactive shell inherits SIGINT ignored, and so would every node (measured: `sleep`
    # then needed SIGTERM, and rclpy nodes saw no KeyboardInterrupt)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except Exception:
        pass
    if nice:
        try:
            os.nice(nice)
        except OSError:
            pass


class Interrupted(Exception):
    """SIGINT or SIGTERM arrived while a graph was running."""


class InterruptLatch:
    """Signal handler that raises `Interrupted` and also latches the signal's name.

    A handler runs between two bytecodes of whatever the main thread is doing; if that is a
    `__del__` (rclpy's Future, a destroyed handle), Python swallows the exception and the run
    would go on. `check()` re-raises a latched interrupt: every wait loop calls it."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.signal_name: str | None = None
        self._old: dict = {}

    def handler(self, signum, frame):  # noqa: ARG002 - signal handler signature
        self.signal_name = signal.Signals(signum).name
        raise Interrupted(self.signal_name)

    def check(self) -> None:
        if self.signal_name is not None:
            raise Interrupted(self.signal_name)

    def arm(self) -> None:
        """Install the handler for SIGINT and SIGTERM (the previous handlers are kept)."""
        self.signal_name = None
        self._old = {s: signal.signal(s, self.handler) for s in self.SIGNALS}

    def hold(self) -> None:
        """Ignore further signals and forget the latched one: the clean-up after an interrupt
        (stopping nodes, draining the recorder) waits in the same loops and must not re-raise."""
        for s in self.SIGNALS:
            signal.signal(s, signal.SIG_IGN)
        self.signal_name = None

    def disarm(self) -> None:
        """Put the handlers from before `arm()` back."""
        for s, h in self._old.items():
            signal.signal(s, h)
        self._old = {}
        self.signal_name = None


#: the process's one latch (signal handlers are per process)
interrupt_latch = InterruptLatch()


class ProcessDied(RuntimeError):
    def __init__(self, proc: "ManagedProcess"):
        self.proc = proc
        super().__init__(f"{proc.name} exited with code {proc.returncode} before the graph was ready\n"
                         f"--- last lines of {proc.log_path} ---\n{proc.log_tail()}")


class GraphTimeout(TimeoutError):
    pass


@dataclass
class ManagedProcess:
    name: str
    cmd: list[str]
    env: dict
    log_path: Path | None
    popen: subprocess.Popen
    started: float = field(default_factory=time.monotonic)
    stopped_by: str | None = None     # None (exited by itself) | SIGINT | SIGTERM | SIGKILL
    returncode: int | None = None
    optional: bool = False            # its exit does not fail check_alive (the graph goes on)
    _log_fh: object = None

    @property
    def pid(self) -> int:
        return self.popen.pid

    def poll(self) -> int | None:
        if self.returncode is None:
            rc = self.popen.poll()
            if rc is not None:
                self.returncode = rc
                self._close_log()
        return self.returncode

    def running(self) -> bool:
        return self.poll() is None

    def _close_log(self):
        if self._log_fh is not None:
            try:
                self._log_fh.close()
            except Exception:
                pass
            self._log_fh = None

    def log_text(self) -> str:
        if self.log_path is None or not self.log_path.exists():
            return ""
        return self.log_path.read_text(errors="replace")

    def log_tail(self, n: int = 30) -> str:
        return "\n".join(self.log_text().splitlines()[-n:])

    def report(self) -> dict:
        return {"name": self.name, "pid": self.pid, "returncode": self.returncode,
                "stopped_by": self.stopped_by or ("exited" if self.returncode is not None else None),
                "log": str(self.log_path) if self.log_path else None, "cmd": self.cmd}


def ros_args(node_name: str | None = None, params: dict | None = None,
             params_file: str | Path | None = None, remaps: dict | None = None) -> list[str]:
    """`--ros-args -r __node:=NAME -p k:=v ... --params-file F` (what a launch file generates)."""
    out: list[str] = []
    if node_name:
        out += ["-r", f"__node:={node_name}"]
    for k, v in (remaps or {}).items():
        out += ["-r", f"{k}:={v}"]
    for k, v in (params or {}).items():
        out += ["-p", f"{k}:={_param_str(v)}"]
    if params_file:
        out += ["--params-file", str(params_file)]
    return ["--ros-args", *out] if out else []


def _param_str(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)  # keeps a '.', so ROS types it as double
    if isinstance(v, str):
        # YAML single-quoted: `-p` values are YAML, and a JSON text ({...}) would parse as a mapping
        return "'" + v.replace("'", "''") + "'"
    return str(v)


class Launcher:
    """Starts and stops node processes of one isolated graph (one ROS_DOMAIN_ID)."""

    def __init__(self, domain_id: int, log_dir: str | Path | None = None, extra_env: dict | None = None):
        self.domain_id = domain_id
        self.log_dir = Path(log_dir) if log_dir else None
        if self.log_dir:
            self.log_dir.mkdir(parents=True, exist_ok=True)
        cpus = sorted(os.sched_getaffinity(0))
        self.extra_env = {LOCKSTEP_CPU_ENV: os.environ.get(LOCKSTEP_CPU_ENV, cpus[domain_id % len(cpus)]),
                          PROFILES_ENV: os.environ.get(PROFILES_ENV) or fastdds_profile_file(),
                          **(extra_env or {})}
        self.procs: dict[str, ManagedProcess] = {}

    # -- start ---------------------------------------------------------------------------------
    def start(self, name: str, cmd: Sequence[str], *, node_name: str | None = None,
              params: dict | None = None, params_file=None, remaps: dict | None = None,
              env: dict | None = None, cwd=None, nice: int = 0, optional: bool = False) -> ManagedProcess:
        if name in self.procs and self.procs[name].running():
            raise RuntimeError(f"{name} already running")
        full = [str(c) for c in cmd] + ros_args(node_name, params, params_file, remaps)
        penv = node_env(self.domain_id, {**self.extra_env, **(env or {})})
        log_path = fh = None
        if self.log_dir:
            log_path = self.log_dir / f"{name}.log"
            fh = open(log_path, "wb")
            out = err = fh
        else:
            out, err = None, None
        popen = subprocess.Popen(full, env=penv, cwd=cwd, stdin=subprocess.DEVNULL, stdout=out,
                                 stderr=subprocess.STDOUT if fh else err, start_new_session=True,
                                 preexec_fn=lambda: _child_setup(nice))
        mp = ManagedProcess(name, full, penv, log_path, popen, optional=optional, _log_fh=fh)
        self.procs[name] = mp
        return mp

    # -- status --------------------------------------------------------------------------------
    def check_alive(self, names: Iterable[str] | None = None) -> None:
        """ProcessDied for the first of ``names`` (default: every process but the optional ones)
        that has exited."""
        for n in (names if names is not None else [n for n, p in self.procs.items() if not p.optional]):
            p = self.procs[n]
            if p.poll() is not None:
                raise ProcessDied(p)

    def exited(self) -> list[ManagedProcess]:
        return [p for p in self.procs.values() if p.poll() is not None]

    def wait_exit(self, name: str, timeout: float | None) -> int | None:
        p = self.procs[name]
        try:
            p.popen.wait(timeout)
        except subprocess.TimeoutExpired:
            pass
        return p.poll()

    # -- stop ----------------------------------------------------------------------------------
    def stop(self, name: str, sigint_timeout: float = 10.0, sigterm_timeout: float = 5.0) -> int:
        """SIGINT (what Ctrl-C / launch sends), then SIGTERM, then SIGKILL; to the process group.
        Returns the exit code (negative = killed by that signal)."""
        p = self.procs[name]
        if p.poll() is None:
            for sig, tmo in ((signal.SIGINT, sigint_timeout), (signal.SIGTERM, sigterm_timeout),
                             (signal.SIGKILL, 10.0)):
                p.stopped_by = sig.name
                _killpg(p.pid, sig)
                try:
                    p.popen.wait(tmo)
                    break
                except subprocess.TimeoutExpired:
                    continue
            p.poll()
        # the group may hold grandchildren that outlived the leader
        if _group_alive(p.pid):
            _killpg(p.pid, signal.SIGKILL)
            _wait_group_gone(p.pid, 5.0)
        return p.returncode

    def stop_all(self, order: Sequence[str] | None = None, **kw) -> dict[str, dict]:
        names = list(order or [])
        names += [n for n in reversed(list(self.procs)) if n not in names]
        for n in names:
            if n in self.procs:
                self.stop(n, **kw)
        return self.report()

    def report(self) -> dict[str, dict]:
        return {n: p.report() for n, p in self.procs.items()}

    def leftovers(self) -> list[int]:
        """pids of any started process (or member of its process group) still alive."""
        left = []
        for p in self.procs.values():
            if p.poll() is None:
                left.append(p.pid)
            elif _group_alive(p.pid):
                left.append(p.pid)
        return left

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop_all()


def _killpg(pgid: int, sig) -> None:
    try:
        os.killpg(pgid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # a zombie leader that we have reaped cannot count; members of the group are live processes
    return _pgid_members(pgid) != []


def _pgid_members(pgid: int) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                stat = f.read()
            fields = stat[stat.rfind(")") + 2:].split()
            state, pg = fields[0], int(fields[2])
            if pg == pgid and state != "Z":
                out.append(int(d))
        except (OSError, ValueError, IndexError):
            continue
    return out


def _wait_group_gone(pgid: int, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end and _pgid_members(pgid):
        time.sleep(0.05)


# ---------------------------------------------------------------------------------------------
class GraphWatcher:
    """Readiness conditions evaluated on the ROS graph of one domain, through an rclpy node.

    Use with an existing node (e.g. a test node) or let it create a private context/node.
    """

    def __init__(self, node=None, domain_id: int | None = None, name: str = "flip_graph_watcher"):
        self._own = node is None
        if node is None:
            import rclpy
            from rclpy.context import Context
            self._ctx = Context()
            rclpy.init(context=self._ctx, domain_id=domain_id, signal_handler_options=_no_signals())
            node = rclpy.create_node(name, context=self._ctx, start_parameter_services=False,
                                     enable_rosout=False)
        self.node = node
        # a node belongs to one executor at a time: reuse the caller's if the node has one
        self._own_executor = node.executor is None
        if self._own_executor:
            from rclpy.executors import SingleThreadedExecutor
            self.executor = SingleThreadedExecutor(context=node.context)
            self.executor.add_node(node)
        else:
            self.executor = node.executor

    def spin_once(self, timeout: float = 0.05) -> None:
        """Run this node's callbacks (subscriptions, service responses) for up to `timeout` s."""
        interrupt_latch.check()
        self.executor.spin_once(timeout_sec=timeout)
        interrupt_latch.check()

    def spin_until(self, pred: Callable[[], bool], timeout: float, what: str = "condition") -> None:
        end = time.monotonic() + timeout
        while not pred():
            if time.monotonic() > end:
                raise TimeoutError(f"timed out after {timeout:.0f} s waiting for {what}")
            self.spin_once(0.05)

    def close(self):
        if self._own_executor:
            self.executor.remove_node(self.node)
            self.executor.shutdown()
        if self._own:
            self.node.destroy_node()
            self._ctx.try_shutdown()

    # -- graph queries -------------------------------------------------------------------------
    def node_names(self) -> set[str]:
        out = set()
        for n, ns in self.node.get_node_names_and_namespaces():
            out.add(n)
            out.add((ns.rstrip("/") + "/" + n) if ns else "/" + n)
        return out

    def services(self) -> set[str]:
        return {n for n, _ in self.node.get_service_names_and_types()}

    def topics(self) -> dict[str, list[str]]:
        return dict(self.node.get_topic_names_and_types())

    def count(self, topic: str) -> tuple[int, int]:
        return self.node.count_publishers(topic), self.node.count_subscribers(topic)

    # -- conditions ------------------------------------------------------------------------------
    def wait_until(self, what: str, pred: Callable[[], bool], timeout: float,
                   launcher: Launcher | None = None, watch: Iterable[str] | None = None,
                   period: float = 0.05) -> None:
        end = time.monotonic() + timeout
        while True:
            interrupt_latch.check()
            if pred():
                return
            if launcher is not None:
                launcher.check_alive(watch)
            if time.monotonic() > end:
                raise GraphTimeout(f"graph not ready after {timeout:.0f} s: {what}\n{self.describe()}")
            time.sleep(period)

    def wait_ready(self, *, nodes: Iterable[str] = (), services: Iterable[str] = (),
                   topics: dict[str, tuple[int, int]] | None = None, timeout: float = 60.0,
                   launcher: Launcher | None = None, watch: Iterable[str] | None = None) -> float:
        """Wait until every node name is in the graph, every service is offered and every topic
        has at least (publishers, subscribers). Returns the wall seconds it took."""
        nodes, services, topics = list(nodes), list(services), dict(topics or {})
        t0 = time.monotonic()

        def missing() -> list[str]:
            miss = []
            if nodes:
                have = self.node_names()
                miss += [f"node {n}" for n in nodes if n not in have]
            if services:
                have_s = self.services()
                miss += [f"service {s}" for s in services if s not in have_s]
            for t, (np_, ns_) in topics.items():
                p, s = self.count(t)
                if p < np_ or s < ns_:
                    miss.append(f"topic {t} pubs {p}/{np_} subs {s}/{ns_}")
            return miss

        state = {"miss": None}

        def pred():
            state["miss"] = missing()
            return not state["miss"]

        try:
            self.wait_until("", pred, timeout, launcher, watch)
        except GraphTimeout as e:
            raise GraphTimeout(f"graph not ready after {timeout:.0f} s; missing: {state['miss']}\n"
                               f"{self.describe()}") from e
        return time.monotonic() - t0

    def describe(self) -> str:
        try:
            return (f"nodes: {sorted(self.node_names())}\nservices: {sorted(self.services())}\n"
                    f"topics: {sorted(self.topics())}")
        except Exception as e:  # noqa: BLE001
            return f"(graph unavailable: {e})"


def _no_signals():
    from rclpy.signals import SignalHandlerOptions
    return SignalHandlerOptions.NO


def python_node_cmd(script: str | Path) -> list[str]:
    """Command line for a Python node script run with this interpreter (stand-in nodes)."""
    return [sys.executable, str(script)]
