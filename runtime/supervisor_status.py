"""What the supervisor says about a launch: SUPERVISOR_STATUS, the status table, the summary.

Built from the supervisor's records of its processes (``runtime.supervisor.Child``), apart
from the process control that keeps those records: one place for the message the dashboard
and ``cassie order`` read and for the text operators and tests read (the table's columns,
the ``robot:``, ``crashed:``, ``degraded:`` and ``result:`` lines of a summary).
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING

from lcmtypes import process_status_t, supervisor_status_t

if TYPE_CHECKING:
    from runtime.supervisor import Child, Supervisor

#: the states of a process that fail a run when it is required
FAILED_STATES = ("failed", "crash_loop")


def required_failed(children: Iterable[Child]) -> list[str]:
    """Required processes that failed (or gave up in a crash loop) at any time."""
    return [c.proc.name for c in children
            if c.proc.required and (c.state in FAILED_STATES or c.ever_failed)]


def crashed(children: Iterable[Child]) -> list[str]:
    """Required processes that crashed at least once (a restart kept the run going, but
    the run's result is a failure: a controller that dies mid-walk is a bug)."""
    return [c.proc.name for c in children if c.proc.required and c.crashes]


def faulted(children: Iterable[Child]) -> list[str]:
    """Required processes that reported a fault (safe mode, a fall) at any time."""
    return [c.proc.name for c in children if c.proc.required and c.fault]


def status_message(sup: Supervisor) -> supervisor_status_t:
    """The launch's full state for SUPERVISOR_STATUS: a row per process, then the
    supervisor's own (so its cost is on record too)."""
    msg = supervisor_status_t()
    msg.profile = sup.profile.name
    msg.state = sup.state
    msg.uptime_s = time.monotonic() - sup.t0
    msg.log_dir = str(sup.log_dir)
    now_ns = time.monotonic_ns()
    for child in sup.children.values():
        p = process_status_t()
        p.name = child.proc.name
        p.host = child.proc.host
        p.state = child.state
        p.required = child.proc.required
        p.pid = child.pid
        p.restarts = child.restarts
        p.crashes = child.crashes
        p.exit_code = child.exit_code
        p.cpu_percent = child.cpu_percent
        p.cpu_s = child.cpu_s
        p.rss_mb = child.rss_mb
        p.loop_rate_hz = child.loop_rate_hz
        p.deadline_misses = child.deadline_misses
        p.last_message_age_s = (now_ns - child.last_msg_ns) / 1e9 if child.last_msg_ns else -1.0
        p.health = child.health
        p.status = child.status
        p.affinity = child.affinity
        p.priority = child.priority
        p.detail = child.detail
        if child.standby is not None and child.standby.poll() is None:
            p.detail = (p.detail + "; " if p.detail else "") + (
                f"standby {child.standby.pid}"
                + ("" if child.standby_ready else " (setting up)"))
        msg.processes.append(p)
    me = process_status_t()
    me.name, me.host, me.state, me.pid = "supervisor", "laptop", sup.state, os.getpid()
    me.cpu_percent = sup.resources.cpu_percent
    me.cpu_s, me.rss_mb, me.priority = sup.resources.own_usage()
    me.last_message_age_s = -1.0
    msg.processes.append(me)
    msg.num_processes = len(msg.processes)
    return msg


def table(sup: Supervisor) -> str:
    """The status table: a row per process, the supervisor's, and the total CPU share."""
    rows = [
        f"{'process':<16}{'state':<11}{'pid':>7}{'rst':>4}{'cpu%':>7}{'MB':>7}"
        f"{'Hz':>9}{'miss':>7}{'age s':>7}  {'sched':<8} status"
    ]
    now_ns = time.monotonic_ns()
    own = sup.resources.cpu_percent
    total = own
    for c in sup.children.values():
        age = f"{(now_ns - c.last_msg_ns) / 1e9:.1f}" if c.last_msg_ns else "-"
        text = c.detail or c.status.split(" | ")[0]  # the node's own first part
        if c.fault and c.fault != c.status:
            text = f"{text} (fault: {c.fault.split(' | ')[0]})"
        if len(text) > 90:
            text = text[:87] + "..."
        rows.append(
            f"{c.proc.name:<16}{c.state:<11}{c.pid or '-':>7}{c.restarts:>4}"
            f"{c.cpu_percent:>7.1f}{c.rss_mb:>7.0f}{c.loop_rate_hz:>9.1f}"
            f"{c.deadline_misses:>7}{age:>7}  {c.priority:<8} {text}"
        )
        total += c.cpu_percent
    rows.append(f"{'supervisor':<16}{sup.state:<11}{os.getpid():>7}{'':>4}"
                f"{own:>7.1f}")
    rows.append(f"{'total':<16}{'':<11}{'':>7}{'':>4}{total:>7.1f}  "
                f"(% of one core; this machine has {os.cpu_count()} cores)")
    return "\n".join(rows)


def robot_lines(children: Iterable[Child]) -> list[str]:
    """What the robot did, from the process that knows it (the sim's truth: distance,
    falls) and the controller's mode, for the summary."""
    lines = []
    for c in children:
        if "walked_m" in c.counters:
            lines.append(f"robot: {c.status.split(' | ')[0]}  (the {c.proc.name}'s truth)")
        elif "mode" in c.counters:
            lines.append(f"controller: {c.status}  ({c.proc.name})")
    return lines


def screen_text(sup: Supervisor) -> str:
    """The periodic picture of the launch: a heading line, the table, the robot lines."""
    text = f"[{sup.profile.name}] {sup.state}, up {time.monotonic() - sup.t0:.0f} s\n"
    return text + table(sup) + "\n" + "".join(
        line + "\n" for line in robot_lines(sup.children.values()))


def summary_text(sup: Supervisor) -> str:
    """The end-of-launch summary: the table, the robot lines, what failed, crashed, rode
    through or was refused, and the ``result:`` line."""
    children = sup.children
    parts = [f"\nsummary of profile {sup.profile.name} after "
             f"{time.monotonic() - sup.t0:.1f} s (logs in {sup.log_dir}):\n",
             table(sup) + "\n"]
    parts += [line + "\n" for line in robot_lines(children.values())]
    bad = required_failed(children.values())
    for name in faulted(children.values()):
        parts.append(f"fault: {name}: {children[name].fault}\n")
        if name not in bad:
            bad.append(name)
    for name in crashed(children.values()):
        c = children[name]
        spare = f" ({c.takeovers} by its standby)" if c.takeovers else ""
        parts.append(f"crashed: {name}: {c.crashes} time(s), restarted {c.restarts} "
                     f"time(s){spare}; last: {c.last_crash} (see its log)\n")
        if name not in bad:
            bad.append(name)
    for c in children.values():
        parts += [f"degraded: {c.proc.name}: {line}\n" for line in degraded_lines(c.counters)]
    for what, n in sup.refused.items():
        parts.append(f"ignored: {n} {what} message(s), malformed or not from this stack; "
                     f"last: {sup.refused_last[what]}\n")
    parts.append("result: " + (f"FAILED ({', '.join(bad)})" if bad else "ok") + "\n")
    return "".join(parts)


def degraded_lines(counters: Mapping[str, float]) -> list[str]:
    """What a process's counters say it rode through (safe-mode episodes that cleared, plan
    fallbacks, rejected inputs): not a failure of the run, but a reader should see it."""
    lines = []
    if (n := int(counters.get("safe_entries", 0))) > 0:
        lines.append(f"{n} safe-mode episode(s), {int(counters.get('safe_recoveries', 0))} "
                     "cleared by themselves")
    if (n := int(counters.get("plan_fallbacks", 0))) > 0:
        lines.append(f"walked on its own steps {n} time(s) without MPFC plans, handed back "
                     f"{int(counters.get('plan_handbacks', 0))}")
    if (n := int(counters.get("inputs_rejected", 0))) > 0:
        lines.append(f"{n} input message(s) rejected at the edge")
    if (n := int(counters.get("tick_errors", 0))) > 0:
        lines.append(f"{n} tick(s) raised and were caught (previous output kept)")
    return lines
