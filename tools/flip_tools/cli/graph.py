"""One isolated graph for a run: the recorder and the nodes as OS processes, a watcher node in this
process; `run_graph` starts one, runs a subcommand's part in it and stops it whatever happened."""
from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

from flip_tools.launcher import Interrupted, _killpg, interrupt_latch
from flip_tools.rosenv import claim_domain, set_process_ros_env

from .common import EXIT_INFRA, EXIT_INTERRUPTED, log
from .params import lockstep_sched, node_cmd, recorder_cmd


#: wall seconds /tf's recorded count must stand still once the simulator's last step is recorded (the
#: recorder reports its counts twice a second)
DERIVED_QUIET_S = 0.6
#: wall seconds the recorder's counts must stand still when no /clock writer is left before it had the
#: simulator's last step (the simulator is gone: that step can no longer reach it), so that what it has
#: queued is written; longer than the second its counts can stand still on a loaded machine
WRITERS_GONE_QUIET_S = 3.0


#: wall seconds sim time must stand still after the controller is paused for the lockstep to count
#: as stopped (the simulator re-sends its state every 50 ms meanwhile, with the same stamp)
PAUSE_CHECK_S = 0.3
#: sim seconds a paused lockstep can still advance: the step under way and its /clock (5 ms grid)
PAUSE_MAX_ADVANCE_S = 0.02


class Graph:
    """One isolated graph: recorder + nodes as OS processes, a watcher node in this process."""

    def __init__(self, out: Path, domain: int | None, cpu_dma_latency: int | None, lockstep_sched: str):
        from flip_tools.cpu_latency import CpuLatencyRequest
        from flip_tools.launcher import LOCKSTEP_SCHED_ENV, GraphWatcher, Launcher
        set_process_ros_env()
        # held until close(): the lockstep's wake-ups of the recorder's CPU (flip_tools.cpu_latency)
        self.cpu_latency = CpuLatencyRequest(cpu_dma_latency)
        if self.cpu_latency.hold():
            log(f"CPU wake-up latency held at {cpu_dma_latency} us (/dev/cpu_dma_latency) for the run")
        elif cpu_dma_latency is not None:
            log(f"CPU wake-up latency not held ({self.cpu_latency.reason}): the lockstep runs slower")
        self.claim = claim_domain(domain if domain is not None else _env_domain())
        self.domain = self.claim.domain_id
        self.out = out
        # the scheduling policy of the pinned simulator and controller (flip_transport.lockstep)
        self.lockstep_sched = lockstep_sched
        self.launcher = Launcher(self.domain, log_dir=out / "logs",
                                 extra_env={LOCKSTEP_SCHED_ENV: self.lockstep_sched})
        self.watcher = GraphWatcher(domain_id=self.domain, name="flip_cli")
        self.node = self.watcher.node
        self.sim_time = None
        self.t_wall0 = time.time()
        log(f"ROS_DOMAIN_ID={self.domain} (loopback); logs in {out / 'logs'}")

    def start_recorder(self, timeout: float = 30.0):
        from std_msgs.msg import String
        # niced: the lockstep loop comes first; best-effort topics queue (depth 10,000) meanwhile
        self.launcher.start("recorder", recorder_cmd(self.out / "bag", self.out / "record_stats.json"),
                            nice=int(os.environ.get("FLIP_RECORDER_NICE", "10")))
        self.recorder_status = {}

        def on_status(m):
            try:
                self.recorder_status = json.loads(m.data)
            except ValueError:
                pass
        self.node.create_subscription(String, "/flip_recorder/status", on_status, 10)
        # the recorder subscribes to the contract topics at start-up: wait for it in the graph
        self.watcher.wait_ready(nodes=["flip_recorder"], topics={"/clock": (0, 1), "/odom": (0, 1)},
                                timeout=timeout, launcher=self.launcher)

    def start_live(self, args, run_info: dict) -> None:
        """--live: the Foxglove WebSocket server (flip_tools.live_node) as an optional process: if it
        fails or dies the run goes on without it (run.json's "live" says which)."""
        if not getattr(args, "live", False):
            return
        from flip_tools.live import start_live
        overrides = dict(e.split("=", 1) for e in (getattr(args, "exe", None) or []))
        info = start_live(self.launcher, args.live_port, overrides.get("live") or os.environ.get("FLIP_LIVE_CMD"),
                          nice=int(os.environ.get("FLIP_RECORDER_NICE", "10")))
        run_info["live"] = info
        if "url" in info:
            print(f"live: {info['url']} — open it in Foxglove", flush=True)
        else:
            log(f"live view failed, the run goes on without it: {info['error']}")

    def release_live(self) -> None:
        """The graph runs (the recorder has matched): the live view may read the streamed topics."""
        from flip_tools.live import release_streams
        release_streams(self.launcher)

    def check_live(self) -> None:
        """Says once, clearly, that the live view has stopped during the run (which goes on)."""
        p = self.launcher.procs.get("live")
        if p is not None and p.poll() is not None and not getattr(self, "_live_gone", False):
            self._live_gone = True
            log(f"live view stopped (exit {p.returncode}), the run goes on without it; "
                f"last lines of {p.log_path}:\n{p.log_tail(5)}")

    def foot_wrench_topics(self) -> list:
        """The foot wrench topics sim_node has publishers on (sim_node makes them whatever its wrench_rate;
        a stand-in simulator has none)."""
        from cassie_flip_sim.foot_wrench import WRENCH_TOPICS
        try:
            pubs = {n for n, _ in self.node.get_publisher_names_and_types_by_node("sim_node", "/")}
        except Exception:  # noqa: BLE001 - no such node (yet): nothing of it to wait for
            return []
        return [t for t in WRENCH_TOPICS if t in pubs]

    def wait_recorder_matched(self, topics, timeout: float) -> float:
        """Until the recorder itself reports a matched publisher on every topic."""
        t0 = time.monotonic()
        end = t0 + timeout

        def missing():
            m = self.recorder_status.get("matched", {})
            return [t for t in topics if m.get(t, 0) < 1]
        while missing():
            self.launcher.check_alive()
            if time.monotonic() > end:
                raise TimeoutError(f"recorder not matched on {missing()} after {timeout:.0f} s "
                                   f"(status {self.recorder_status})")
            self.spin(0.05)
        return time.monotonic() - t0

    def start_node(self, role: str, args, params: dict):
        # no `-r __node:=` remap: it would rename every node of the process (sim_node also runs
        # sim_node_services, planner_node planner_clock); the nodes' own names are the contract
        return self.launcher.start(role, node_cmd(role, args), params=params)

    def start_state_publisher(self, args):
        """The robot's /tf and /tf_static (cassie_flip_sim.state_publisher), niced like the recorder:
        it reads the lockstep's streams beside it, one of the subscribers the simulator waits for
        (SIM_MIN_SUBSCRIBERS)."""
        return self.launcher.start("state", node_cmd("state", args),
                                   nice=int(os.environ.get("FLIP_RECORDER_NICE", "10")))

    def follow_clock(self):
        """Subscribe to /clock on a node no executor spins (no 2 kHz callbacks in this process);
        `sim_now()` takes what is queued and keeps the newest."""
        import rclpy
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        self._clock_node = rclpy.create_node("flip_cli_clock", context=self.node.context,
                                             start_parameter_services=False, enable_rosout=False)
        self._clock_sub = self._clock_node.create_subscription(
            Clock, "/clock", lambda m: None, QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))

    def follow_contact_events(self):
        """Subscribe to /contact_events (latched, as sim_node offers it) on the clock's node;
        `contact_events()` takes the queued ones as (event, sim time)."""
        from flip_msgs.msg import ContactEvent
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        self._events_sub = self._clock_node.create_subscription(
            ContactEvent, "/contact_events", lambda m: None,
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))

    def contact_events(self) -> list[tuple[int, float]]:
        sub, out = self._events_sub, []
        with sub.handle:
            while (r := sub.handle.take_message(sub.msg_type, False)) is not None:
                out.append((int(r[0].event), r[0].header.stamp.sec + 1e-9 * r[0].header.stamp.nanosec))
        return out

    def sim_now(self):
        sub = getattr(self, "_clock_sub", None)
        if sub is not None:
            with sub.handle:
                while True:
                    r = sub.handle.take_message(sub.msg_type, False)
                    if r is None:
                        break
                    self.sim_time = r[0].clock.sec + 1e-9 * r[0].clock.nanosec
        return self.sim_time

    def spin(self, timeout: float):
        self.watcher.spin_once(timeout)

    def wait_recorder_drained(self, quiet_s: float = 1.0, timeout: float = 30.0) -> None:
        """Until the recorder has written the last /clock step the simulator published (its status
        carries the newest /clock stamp it recorded), then (or, when that cannot be known: no sim
        time seen, a recorder without that field, from the start) until its message counts have
        stopped growing for ``quiet_s``: /tf, made from the simulator's states by state_publisher,
        comes after them.  It is niced and queues behind the lockstep loop: on a loaded machine its
        counts can stand still for a second while the tail of the run is still queued (measured:
        the last 3 steps of a `flip stand` lost that way)."""
        if "recorder" not in self.launcher.procs or self.launcher.procs["recorder"].poll() is not None:
            return
        final = self.sim_now()
        final_ns = None if final is None else int(round(final * 1e9))
        end = time.monotonic() + timeout
        last, since, derived = None, time.monotonic(), False
        while time.monotonic() < end:
            self.spin(0.1)
            st = self.recorder_status
            if final_ns is not None and "last_clock_ns" in st:
                if st["last_clock_ns"] is not None and st["last_clock_ns"] >= final_ns:
                    # then /tf until its count stands still (a paused lockstep re-sends its state)
                    final_ns, derived, quiet_s = None, True, min(quiet_s, DERIVED_QUIET_S)
                    last, since = None, time.monotonic()
                elif st.get("matched", {}).get("/clock", 1) == 0:
                    # no /clock writer is left and the last step has not reached the recorder: it cannot
                    # come any more, so only what the recorder has queued is waited for
                    log(f"the recorder's newest step is sim t = {1e-9 * (st['last_clock_ns'] or 0):.3f} s of "
                        f"{final:.3f} s and the simulator is gone: waiting for its queue only")
                    final_ns, quiet_s = None, max(quiet_s, WRITERS_GONE_QUIET_S)
                    last, since = None, time.monotonic()
                continue
            counts = st.get("counts", {})
            if derived and "/tf" not in counts:
                return
            counts = json.dumps(counts.get("/tf") if derived else counts, sort_keys=True)
            if counts != last:
                last, since = counts, time.monotonic()
            elif time.monotonic() - since >= quiet_s:
                return
        log(f"WARNING: the recorder had not written the last step (sim t = {final}) after {timeout:.0f} s; "
            f"status {self.recorder_status}")

    def _pause_controller(self) -> str | None:
        """Stop the lockstep where it is before anything is stopped: the controller is paused
        (SIGSTOP), the simulator waits for its command and sim time stands, so the recorder can
        write the run's tail before the writers go (stopping the simulator while the recorder was
        0.5 s of sim time behind lost that tail on a loaded machine).  The paused role, or None (no
        controller running beside a running simulator)."""
        procs = self.launcher.procs
        if not all(r in procs and procs[r].poll() is None for r in ("sim", "tsc")):
            return None
        _killpg(procs["tsc"].pid, signal.SIGSTOP)
        # a simulator that does not wait for the controller (realtime mode, a stand-in) goes on:
        # the controller is let go again and the run stops as it did before
        t0 = self.sim_now()
        t_last, since, end = t0, time.monotonic(), time.monotonic() + 2.0
        while time.monotonic() < end:
            self.spin(0.02)
            now = self.sim_now()
            if t0 is None or now is None or now - t0 > PAUSE_MAX_ADVANCE_S:
                break
            if now != t_last:
                t_last, since = now, time.monotonic()
            elif time.monotonic() - since >= PAUSE_CHECK_S:
                return "tsc"
        _killpg(procs["tsc"].pid, signal.SIGCONT)
        return None

    def stop(self, order) -> dict:
        # the recorder first gets what the nodes sent while they are still there (Fast DDS drops the
        # samples of a writer that is gone: a recorder stalled at the end lost the run's tail), then
        # the nodes stop (in the given order), the recorder last, once it has written what they sent
        order = [n for n in order if n in self.launcher.procs]
        self.check_live()
        paused = self._pause_controller()
        if paused:
            log(f"lockstep paused at sim t = {self.sim_time:.3f} s (controller stopped): the recorder writes the tail")
        if paused or sim_lingers(self):
            self.wait_recorder_drained()
        for n in order:
            if n == paused:
                _killpg(self.launcher.procs[n].pid, signal.SIGCONT)
            self.launcher.stop(n)
        self.wait_recorder_drained()
        report = self.launcher.stop_all(order=order + ["recorder"])
        left = self.launcher.leftovers()
        if left:
            log(f"WARNING: processes left behind: {left}")
        for n, r in report.items():
            log(f"{n}: exit {r['returncode']} ({r['stopped_by']})")
        return report

    def close(self):
        from flip_tools.shm import clean_zombies
        try:
            if getattr(self, "_clock_node", None) is not None:
                self._clock_node.destroy_node()
            self.watcher.close()
        finally:
            self.claim.release()
            self.cpu_latency.release()
            # shared-memory files of killed processes (this graph's or earlier ones')
            self.shm_cleaned = clean_zombies()
            if self.shm_cleaned["files"]:
                log(f"removed {self.shm_cleaned['files']} shared-memory files of processes that are gone "
                    f"({self.shm_cleaned['bytes'] / 1e6:.1f} MB)")


def _env_domain():
    v = os.environ.get("FLIP_ROS_DOMAIN_ID")
    return int(v) if v else None


def sim_lingers(graph: Graph) -> bool:
    """sim_node (``linger``) says in its log that it ran its duration: a free-running sim can end
    before this process has seen any of its /clock."""
    path = graph.out / "logs" / "sim.log"
    try:
        return "lingering at sim t" in path.read_text(errors="replace")[-4000:]
    except OSError:
        return False


def run_graph(args, out: Path, mode: str, run_info: dict, extra: dict, stop_order: list[str], body):
    """A graph for ``out`` (--domain, --cpu-dma-latency, --lockstep-sched of ``mode``) in which
    ``body(graph)`` runs and gives the exit code; every process is stopped afterwards (in
    ``stop_order``, the recorder last) whatever happened.  An interrupt is exit 130, an error
    (a node died, a timeout) exit 3 with ``extra["error"]``.  Returns (exit code, graph or None
    when it could not be made, the processes' stop report)."""
    interrupt_latch.arm()
    graph, report, rc = None, {}, EXIT_INFRA
    try:
        graph = Graph(out, args.domain, args.cpu_dma_latency, lockstep_sched(args, mode))
        run_info["ros_domain_id"] = graph.domain
        run_info["cpu_dma_latency"] = graph.cpu_latency.info()
        run_info["lockstep_sched"] = graph.lockstep_sched
        rc = body(graph)
    except Interrupted as e:
        log(f"interrupted ({e}); stopping everything")
        rc = EXIT_INTERRUPTED
    except Exception as e:  # noqa: BLE001 - graph timeout, a node died, ...
        if interrupt_latch.signal_name is not None:
            # the interrupt raised inside an extension's call (rclpy's pybind11) comes out as its error
            log(f"interrupted ({interrupt_latch.signal_name}: {e}); stopping everything")
            rc = EXIT_INTERRUPTED
        else:
            log(f"ERROR: {e}")
            extra["error"] = str(e)
            rc = EXIT_INFRA
    finally:
        interrupt_latch.hold()
        if graph is not None:
            report = graph.stop(stop_order)
            graph.close()
            run_info["shm_cleaned"] = getattr(graph, "shm_cleaned", None)
        interrupt_latch.disarm()
    return rc, graph, report
