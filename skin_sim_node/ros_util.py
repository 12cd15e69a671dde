"""Shared rclpy plumbing: process start/stop, executors, precise periodic loops, logging.

Every executable (node, bridge, simulated device, mock tool, echo baseline) starts with
:func:`run_nodes`, so all handle SIGINT and SIGTERM the same way and exit 0.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import signal
import struct
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from msgs_schema.spec import ConfigError

try:  # rclpy >= 7 (Jazzy): far less CPU per callback at 1 kHz than the default executors
    from rclpy.experimental import EventsExecutor
except ImportError:  # pragma: no cover - older rclpy
    EventsExecutor = None  # type: ignore[assignment]


HAPTIC_TRANSPORTS = "UDPv4"
"""Fast DDS builtin transports of every skin-sim process (``FASTDDS_BUILTIN_TRANSPORTS``, unless the caller set it).

Why not the default (shared memory + UDPv4): opening the shared-memory port of a participant that joins runs a
health check that waits about 333 ms on a healthy idle port and holds the receive path meanwhile (Fast DDS
2.14, eProsima/Fast-DDS#6535). A reader joining ``tool/wrench`` (``ros2 topic echo``, RViz, a recorder) then froze
the node's pose input for 334-338 ms: in 11 of 38 join trials here with shared memory, 0 of 24 with UDPv4 only (the joiner
keeping the default transports; ``docs/performance_rate.md``). Under ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``
rmw_fastrtps installs its own transports, shared memory included, and this setting has no effect."""


_interrupts = [0]


def _quiet_first_interrupt(_signum, _frame) -> None:
    """SIGINT: nothing on the first (rclpy's own handler shuts the context down), KeyboardInterrupt after."""
    _interrupts[0] += 1
    if _interrupts[0] > 1:
        raise KeyboardInterrupt


def make_executor(kind: str = "events", context=None):
    """``events`` (rclpy.experimental.EventsExecutor, if present) or ``single``, on ``context``."""
    if kind == "events" and EventsExecutor is not None:
        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


UDP_LOOPBACK_PROFILE = Path(__file__).with_name("fastdds_localhost_udp.xml")
"""Fast DDS profile of the haptic processes under ``LOCALHOST`` discovery: UDPv4 only, unicast discovery to 127.0.0.1,
no multicast (the file says why)."""


def localhost_udp_env(env, keep_shm: bool = False) -> tuple[dict[str, str], str]:
    """Environment changes that keep a haptic process (node, bridge, device) off shared memory under ``LOCALHOST``.

    Under ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` rmw_fastrtps installs shared memory + UDPv4 itself, and a
    joining participant's shared-memory port freezes the receive path for ~333 ms (eProsima/Fast-DDS#6535). With
    ``SYSTEM_DEFAULT`` rmw leaves the transports to the profile, :data:`UDP_LOOPBACK_PROFILE`, which keeps the
    discovery on this host (unicast to 127.0.0.1, no multicast) without shared memory.

    Returns the variables to set (empty: leave the process as it is) and a one-line reason. Nothing changes unless
    the range is ``LOCALHOST``, the RMW is Fast DDS, and neither a profile file nor static peers are set (the user's
    own configuration wins); never ``SYSTEM_DEFAULT`` without the profile (that would be multicast discovery).
    """
    rng = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper()
    why = None
    if rng != "LOCALHOST":
        why = f"discovery range {rng or 'unset'}: rmw_fastrtps's transports as configured"
    elif keep_shm:
        why = "LOCALHOST with rmw_fastrtps's shared memory (asked for)"
    elif env.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp") not in ("rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp"):
        why = f"RMW {env['RMW_IMPLEMENTATION']}: transports left to it"
    elif env.get("FASTRTPS_DEFAULT_PROFILES_FILE") or env.get("FASTDDS_DEFAULT_PROFILES_FILE"):
        why = "LOCALHOST with the user's Fast DDS profile file"
    elif env.get("ROS_STATIC_PEERS"):
        why = "LOCALHOST with ROS_STATIC_PEERS (rmw applies them only with its own transports)"
    elif not UDP_LOOPBACK_PROFILE.is_file():
        why = f"LOCALHOST with shared memory: {UDP_LOOPBACK_PROFILE} is missing"
    if why is not None:
        return {}, why
    updates = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT", "FASTRTPS_DEFAULT_PROFILES_FILE": str(UDP_LOOPBACK_PROFILE)}
    return updates, f"LOCALHOST discovery over UDPv4 on this host, no shared memory ({UDP_LOOPBACK_PROFILE.name})"


def run_nodes(factories: list[Callable[[], Node | list[Node]]], args=None, executor: str = "events") -> int:
    """Init rclpy, build the nodes, spin until SIGINT/SIGTERM, then stop and destroy them.

    rclpy's default signal handlers shut the context down on SIGINT and SIGTERM. The
    wheel's EventsExecutor never runs callbacks from ``spin()`` without a timeout
    (measured: it busy-loops), so it is driven by ``spin_once(timeout_sec=0.1)``. A node
    may define ``stop()``; it is called before ``destroy_node()``. Returns the exit code.
    """
    os.environ.setdefault("FASTDDS_BUILTIN_TRANSPORTS", HAPTIC_TRANSPORTS)  # before any participant exists
    # rclpy's C-level handler shuts the context down on SIGINT, then calls the handler it replaced.
    # Python's default one raises KeyboardInterrupt wherever the main thread is, at 1 kHz most often
    # inside a timer callback, where the EventsExecutor logs it through a rosout publisher that is
    # already gone ("Failed to publish log message to rosout"). A first Ctrl-C that raises nothing leaves the
    # shutdown to rclpy, and the loop below ends on rclpy.ok(); a second one (start-up still compiling, or a
    # hung clean-up) interrupts as usual.
    signal.signal(signal.SIGINT, _quiet_first_interrupt)
    try:
        rclpy.init(args=args)
    except Exception as exc:  # rclpy's RCLError (not importable by a public name): e.g. a params file rcl cannot parse
        if type(exc).__name__ != "RCLError":
            raise
        print(f"error: {str(exc).strip().splitlines()[0]}; the node does not start", file=sys.stderr, flush=True)
        return 2
    nodes = []
    code = 0
    try:
        for f in factories:
            made = f()  # a node, or a list of them (a composed bridge: one bridge per hand of the node before it)
            nodes.extend(made if isinstance(made, list) else [made])
        # Start-up objects (numba, rclpy, messages) move to a permanent generation, so the
        # cyclic GC stops rescanning them: measured, a gen-2 pass stalled the haptic thread 55 ms.
        gc.collect()
        gc.freeze()
        ex = make_executor(executor)
        for n in nodes:
            ex.add_node(n)
        while rclpy.ok():
            ex.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        if isinstance(exc, ConfigError) and not nodes:  # a bad parameter at start-up: one line, no traceback, exit 2
            print(f"error: {exc}; the node does not start", file=sys.stderr, flush=True)
            code = 2
        elif rclpy.ok():  # a real error (e.g. at start-up): say it, exit non-zero
            import traceback

            traceback.print_exc()
            print(f"fatal: {exc}", flush=True)
            code = 1
        # else: a callback raced the SIGINT/SIGTERM shutdown ("context is invalid"): a clean exit
    finally:
        for n in reversed(nodes):  # the last built first: a node built on an earlier one stops before it
            stop = getattr(n, "stop", None)
            if stop:
                stop()
            try:
                n.destroy_node()
            except Exception:
                pass
        rclpy.try_shutdown()
    return code


def spin_context(executor, context, stop: threading.Event) -> None:
    """Spin ``executor`` in a background thread until ``stop`` is set or ``context`` shuts down."""
    while not stop.is_set() and context.ok():
        try:
            executor.spin_once(timeout_sec=0.05)
        except Exception:
            if not context.ok():
                return
            raise


# --- scheduling levers (Linux) -------------------------------------------------------
_CLOCK_MONOTONIC = 1  # <time.h>; time.perf_counter_ns reads this clock on Linux
_TIMER_ABSTIME = 1
_PR_SET_TIMERSLACK = 29  # <linux/prctl.h>
OWN_THREAD_PREFIX = "skin-"
"""Kernel name prefix of skin-sim's own loop threads (:func:`start_own_thread`): every :class:`PeriodicLoop` (the
node's clock, a simulated device's loop), a bridge's servo thread and node link. Each sets its own scheduling (its
``rt_priority``, or none), so a process-wide priority change (:func:`set_pid_realtime` with ``skip_own``) leaves them
at theirs; ``ps -L`` / ``/proc/<pid>/task/*/comm`` show which thread runs at what, and ``bench-device`` splits a
process's CPU by them."""


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


try:  # ctypes.CDLL releases the GIL for the duration of each foreign call
    _LIBC = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    _LIBC.clock_nanosleep.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Timespec), ctypes.c_void_p]
except (OSError, AttributeError):  # pragma: no cover - not glibc/Linux
    _LIBC = None  # type: ignore[assignment]


def sleep_until_ns(deadline_ns: int) -> None:
    """Sleep until ``deadline_ns`` on CLOCK_MONOTONIC (``time.perf_counter_ns``'s clock).

    ``clock_nanosleep(TIMER_ABSTIME)``: a preemption between reading the clock and sleeping
    cannot push the wake-up past the deadline, and the GIL is free while asleep.
    """
    if _LIBC is None:  # pragma: no cover
        rem = deadline_ns - time.perf_counter_ns()
        if rem > 0:
            time.sleep(rem / 1e9)
        return
    ts = _Timespec(deadline_ns // 1_000_000_000, deadline_ns % 1_000_000_000)
    _LIBC.clock_nanosleep(_CLOCK_MONOTONIC, _TIMER_ABSTIME, ctypes.byref(ts), None)  # EINTR: the caller loops


def set_timer_slack_ns(slack_ns: int) -> bool:
    """prctl(PR_SET_TIMERSLACK) for the calling thread (Linux default 50 us; RT threads have 0)."""
    return _LIBC is not None and _LIBC.prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(slack_ns), 0, 0, 0) == 0


def start_own_thread(thread: threading.Thread, name: str) -> bool:
    """Start ``thread`` and name it ``skin-<name>`` in the kernel (15 bytes at most, the rest cut) before returning:
    a thread that sets its own scheduling, so a process-wide change made next (a second bridge's) passes it by
    (:data:`OWN_THREAD_PREFIX`). ``Thread.start`` returns once the thread runs and has its ``native_id``; the name is
    written to its ``/proc/self/task/<tid>/comm``. False where that is missing (not Linux)."""
    thread.start()
    try:
        with open(f"/proc/self/task/{thread.native_id}/comm", "wb") as f:
            f.write((OWN_THREAD_PREFIX + name).encode()[:15])
        return True
    except OSError:  # pragma: no cover - not Linux, or the thread already ended
        return False


def thread_names(pid: int) -> dict[int, str]:
    """``{tid: kernel name}`` of every thread of process ``pid`` (Linux ``/proc``; a thread that ends meanwhile is
    left out)."""
    names = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/comm") as f:
                names[int(tid)] = f.read().strip()
        except OSError:
            continue
    return names


def set_realtime(priority: int, tid: int = 0, reset_on_fork: bool = True) -> str | None:
    """SCHED_FIFO at ``priority`` (1-99) for thread ``tid`` (0: the calling thread).

    ``reset_on_fork``: SCHED_RESET_ON_FORK, so processes it starts run normally; note that the
    kernel applies it to new threads too (they start at normal priority). Returns None on
    success, else the reason (e.g. no CAP_SYS_NICE, or no RT budget in this cgroup); the caller
    logs it and carries on at normal priority.
    """
    policy = os.SCHED_FIFO | (os.SCHED_RESET_ON_FORK if reset_on_fork else 0)
    try:
        os.sched_setscheduler(tid, policy, os.sched_param(priority))
        return None
    except (OSError, AttributeError) as exc:
        return f"SCHED_FIFO {priority} not permitted ({exc}); running at normal priority"


def set_process_realtime(priority: int, reset_on_fork: bool = True, skip_own: bool = False) -> str | None:
    """:func:`set_realtime` for every thread of this process (DDS threads included); without
    ``reset_on_fork``, threads started later by one of them inherit it; ``skip_own``: as :func:`set_pid_realtime`."""
    return set_pid_realtime(os.getpid(), priority, reset_on_fork, skip_own)


def set_pid_realtime(pid: int, priority: int, reset_on_fork: bool = True, skip_own: bool = False) -> str | None:
    """:func:`set_realtime` for every thread of process ``pid``; with ``skip_own``, not for the threads named
    :data:`OWN_THREAD_PREFIX` (each set its own priority: in one process with the node, a second bridge's change
    raised the first bridge's node link from 79 and the node's clock from 50 to its own 80)."""
    names = thread_names(pid)
    errors = [
        set_realtime(priority, tid, reset_on_fork)
        for tid, name in names.items()
        if not (skip_own and name.startswith(OWN_THREAD_PREFIX))
    ]
    return next((e for e in errors if e), None)


CPU_LATENCY_DEVICE = "/dev/cpu_dma_latency"
_cpu_latency: tuple[int, int] | None = None  # (fd, us): this process's one PM QoS request, held until it exits


def hold_cpu_latency(us: int) -> str | None:
    """Hold a PM QoS CPU latency request of ``us`` microseconds for the rest of this process (Linux
    ``Documentation/power/pm_qos_interface.rst``: the request stands while ``/dev/cpu_dma_latency`` is open): idle
    CPUs stay out of idle states slower than that to leave. cyclictest (rt-tests) holds 0 while it measures, for the
    same reason. One request per process, the lowest asked. Returns None, or why it is not held (no permission, no
    such device)."""
    global _cpu_latency
    if _cpu_latency is not None and _cpu_latency[1] <= us:
        return None
    try:
        fd = os.open(CPU_LATENCY_DEVICE, os.O_WRONLY | os.O_CLOEXEC)
    except OSError as exc:
        return f"CPU latency request not held ({exc.strerror}: {CPU_LATENCY_DEVICE})"
    try:
        os.write(fd, struct.pack("i", int(us)))  # the kernel reads a native s32
    except OSError as exc:
        os.close(fd)
        return f"CPU latency request not held ({exc.strerror})"
    if _cpu_latency is not None:
        os.close(_cpu_latency[0])
    _cpu_latency = (fd, int(us))
    return None


def set_affinity(cpus, tid: int = 0) -> str | None:
    """Pin thread ``tid`` (0: calling) to ``cpus``; None on success, else the reason."""
    try:
        os.sched_setaffinity(tid, set(cpus))
        return None
    except (OSError, ValueError) as exc:
        return f"cpu affinity {sorted(cpus)} not applied ({exc})"


@dataclass(frozen=True)
class LoopTiming:
    """How a :class:`PeriodicLoop` waits for its deadlines and is scheduled.

    Attributes
    ----------
    abs_sleep : bool
        Sleep with ``clock_nanosleep(TIMER_ABSTIME)`` to the deadline (GIL free); else
        ``time.sleep(deadline - now)``. Either way deadlines advance by whole periods, so
        the schedule never drifts.
    spin_ns : int
        Busy-wait this tail before each deadline (0: none). The wait calls ``time.sleep(0)``
        in a loop, so other threads may take the GIL meanwhile.
    rt_priority : int
        SCHED_FIFO priority of the loop thread (0: normal scheduling).
    cpus : tuple of int
        CPUs to pin the loop thread to (empty: no pinning).
    timer_slack_ns : int
        prctl timer slack of the loop thread (< 0: keep the kernel's 50 us default).
    """

    abs_sleep: bool = True
    spin_ns: int = 0
    rt_priority: int = 0
    cpus: tuple[int, ...] = ()
    timer_slack_ns: int = -1


class PeriodicLoop:
    """Run ``fn(now_ns, elapsed_ns)`` every ``period_ns`` in a thread, to an absolute deadline.

    Sleeps to each deadline (see :class:`LoopTiming` for the levers; measured in
    ``docs/performance_rate.md``). A tick that comes more than one period late counts as an
    overrun and the schedule resynchronises instead of bursting. ``period_ns`` may be changed
    live. Scheduling problems (no RT permission) are collected in :attr:`warnings`, and
    ``on_warning`` (if given) is called with each.
    """

    def __init__(
        self,
        period_ns: int,
        fn: Callable[[int, int], None],
        name: str = "haptic-loop",
        timing: LoopTiming | None = None,
        on_warning: Callable[[str], None] | None = None,
    ):
        self.period_ns = int(period_ns)
        self.fn = fn
        self.timing = timing or LoopTiming()
        self.on_warning = on_warning
        self.warnings: list[str] = []
        self.overruns = 0
        self.ticks = 0
        self._reported: set[type] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the loop thread, named ``skin-<name>`` (:func:`start_own_thread`)."""
        start_own_thread(self._thread, self._thread.name)

    @property
    def native_id(self) -> int | None:
        """The loop thread's kernel thread id (None before :meth:`start`)."""
        return self._thread.native_id

    def stop(self) -> None:
        """Ask the loop to stop and join its thread (up to 2 s; not from the loop thread itself)."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)

    def _setup_thread(self) -> None:
        t = self.timing
        problems = []
        if t.rt_priority > 0:
            problems.append(set_realtime(t.rt_priority))
        if t.cpus:
            problems.append(set_affinity(t.cpus))
        if t.timer_slack_ns >= 0 and not set_timer_slack_ns(t.timer_slack_ns):
            problems.append(f"timer slack {t.timer_slack_ns} ns not applied")
        for msg in filter(None, problems):
            self.warnings.append(f"{self._thread.name}: {msg}")
            if self.on_warning:
                self.on_warning(self.warnings[-1])

    def _wait(self, nxt: int) -> None:
        clock = time.perf_counter_ns
        t = self.timing
        wake = nxt - t.spin_ns
        if t.abs_sleep:
            while clock() < wake and not self._stop.is_set():
                sleep_until_ns(wake)
        else:
            rem = wake - clock()
            if rem > 0:
                time.sleep(rem / 1e9)
        while t.spin_ns and clock() < nxt:
            time.sleep(0)

    def _run(self) -> None:
        self._setup_thread()
        clock = time.perf_counter_ns
        last = clock()
        nxt = last + self.period_ns
        while not self._stop.is_set():
            self._wait(nxt)
            now = clock()
            try:
                self.fn(now, now - last)
            except Exception as exc:  # keep the loop alive; report once per type
                if not rclpy.ok():
                    break  # context shut down (SIGINT/SIGTERM): publishers are gone
                if type(exc) not in self._reported:
                    self._reported.add(type(exc))
                    print(f"{self._thread.name}: tick failed: {exc!r}", flush=True)
            last = now
            self.ticks += 1
            nxt += self.period_ns
            after = clock()
            if after > nxt + self.period_ns:
                self.overruns += 1
                nxt = after + self.period_ns


def ros_now_ns(node) -> int:
    """The node clock's time now, in nanoseconds."""
    return node.get_clock().now().nanoseconds
