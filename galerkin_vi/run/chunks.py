"""Long runs in chunks: a progress bar, Ctrl-C that stops a compiled run, terminal events.

A compiled loop does not return to Python until it is done, so a
KeyboardInterrupt waits for its end, a minute or more for a long run, and the
states computed so far would be lost with it. A run of more
than ``FIRST_CHUNK`` steps therefore goes in chunks: between them Python
updates the progress bar, sees Ctrl-C (which ends the run with the states of
the chunks completed, status ``INTERRUPTED``) and asks whether a terminal event
has occurred (which ends it too: the steps after the event are not computed).

The chunks' sizes depend on the number of coordinates only, never on a clock,
so that a run's result does not depend on the machine's load: ``CHUNK_WORK``
coordinate-steps per chunk (200 000 steps of a pendulum, 2000 of a 100-mass
chain: well under a second, see docs/performance.md). Each chunk continues
from the state the previous one ended in, like :meth:`Integrator.stream`: the
result equals one call's up to round-off at the joins (every chunk starts its
iteration afresh and without the compensation bits of the summed positions).

The joins sit at multiples of ``JOIN`` = 5040 steps (divisible by 1 to 10, 12,
14, 15, 16, 18, 20, 21, 24, 28, 30, 35, 36, 40, ...) and of ``save_every``: for
every ``save_every`` that divides ``JOIN`` they are the same steps as those of
the run that saves every step, so its saved rows are every k-th row of that
run bit for bit, however long the run.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from .trajectory import Trajectory

if TYPE_CHECKING:
    from ..loops.abi import LoopResult
    from .spec import Segment

__all__ = [
    "CHUNK_WORK",
    "JOIN",
    "FIRST_CHUNK",
    "MIN_CHUNK",
    "PROGRESS_AFTER",
    "ProgressBar",
    "chunk_steps",
    "run_in_chunks",
    "single_call",
]

#: the steps at which chunks join are multiples of this (a multiple of 1 to 10)
JOIN = 5040
#: steps of the first call; shorter runs are one call
FIRST_CHUNK = JOIN
#: coordinate-steps per later chunk
CHUNK_WORK = 200_000
#: fewest steps of a later chunk (each chunk's cold start costs about one iteration)
MIN_CHUNK = 1000
#: runs predicted to take longer show a progress bar on a terminal (progress=None)
PROGRESS_AFTER = 2.0


def chunk_steps(n: int, save_every: int) -> int:
    """Steps per chunk after the first: about ``CHUNK_WORK / n``, in whole ``JOIN``s and
    whole saved intervals."""
    return _multiple(_multiple(max(MIN_CHUNK, CHUNK_WORK // max(n, 1)), JOIN), save_every)


def single_call(n_steps: int, save_every: int) -> bool:
    """Whether a run of ``n_steps`` is one compiled call (not chunked)."""
    return n_steps <= _multiple(FIRST_CHUNK, save_every)


def run_in_chunks(
    first: Segment,
    run_chunk: Callable,
    restart: Callable,
    progress: bool | None,
    stop: Callable | None = None,
) -> tuple[Trajectory, LoopResult, bool]:
    """Run the segment ``first`` in chunks.

    Parameters
    ----------
    first : Segment
        The whole run: its start state and grid.
    run_chunk : callable
        ``run_chunk(segment) -> (trajectory, LoopResult)``, one compiled call.
    restart : callable
        ``restart(q, p, t) -> (q0, p0, v0)``, the start of the next chunk.
    progress : bool or None
        Show a tqdm bar: always, never, or (None) when the first chunk's time
        predicts more than ``PROGRESS_AFTER`` seconds and stderr is a terminal
        (the clock decides the bar only, never the chunks).
    stop : callable, optional
        ``stop(chunk) -> bool`` after each chunk: True ends the run there.

    Returns
    -------
    trajectory, result, interrupted
        The whole run's trajectory, the :class:`LoopResult` with the steps done
        counted from the run's start, and whether Ctrl-C ended it (the
        trajectory then holds the chunks completed).
    """
    n_steps, save_every, t0, h = first.n_steps, first.save_every, first.t0, first.h
    steps = min(n_steps, _multiple(FIRST_CHUNK, save_every))
    bar = ProgressBar(progress, n_steps)
    traj, result = run_chunk(first if steps == n_steps else first._replace(n_steps=steps))
    left = n_steps - steps
    if result.status != 0 or left == 0 or (stop is not None and stop(traj)):
        return traj, result, False
    parts, done_steps, last = [traj], steps, traj
    chunk = chunk_steps(traj.q.shape[1], save_every)
    bar.update(done_steps)
    interrupted = False
    try:
        while left > 0:
            steps = min(chunk, left)
            q_start = last.q_reduced[-1] if last.q_reduced is not None else last.q[-1]
            t_start = t0 + done_steps * h  # not last.t[-1]: no rounding accumulates
            q, p, v = restart(q_start, last.p[-1], t_start)
            segment = first._replace(q0=q, p0=p, v0=v, t0=t_start, n_steps=steps)
            part, result = run_chunk(segment)
            part = carry_turns(last, part)
            parts.append(part)
            last = part
            bar.update(done_steps + result.steps)
            if result.status != 0:
                done_steps += result.steps
                break
            done_steps += steps
            left -= steps
            if stop is not None and stop(part):
                break
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
    return _stitched(parts, t0, h), result._replace(steps=done_steps), interrupted


class ProgressBar:
    """A tqdm bar of a run: always (``progress=True``), never (``False``), or
    (``None``) when the time so far predicts more than ``PROGRESS_AFTER`` seconds to
    go and stderr is a terminal; the clock decides the bar only, never the work.

    ``update(done)`` takes the work done so far (steps, or physical time), out of
    ``total``; the decision is taken at the first update with ``done > 0``.
    """

    def __init__(self, progress: bool | None, total: float, unit: str = "step") -> None:
        self.progress, self.total, self.unit = progress, float(total), unit
        self.start = time.perf_counter()
        self.bar = None
        self.shown = 0.0

    def update(self, done: float) -> None:
        if self.bar is None and self.progress is not False and done > 0:
            elapsed = time.perf_counter() - self.start
            predicted = elapsed * (self.total / done - 1.0)
            if self.progress or (predicted > PROGRESS_AFTER and sys.stderr.isatty()):
                from tqdm.auto import tqdm

                self.bar = tqdm(total=self.total, unit=self.unit, unit_scale=True, leave=False)
            self.progress = self.bar is not None
        if self.bar is not None:
            self.bar.update(min(done, self.total) - self.shown)
            self.shown = min(done, self.total)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def carry_turns(previous: Trajectory, part: Trajectory) -> Trajectory:
    """``part``, which started from ``previous``'s last reduced angles, with the whole
    turns of the angles that ``previous`` had made added back."""
    if previous.q_reduced is None:
        return part
    return replace(part, q=part.q + (previous.q[-1] - previous.q_reduced[-1]))


def _stitched(parts: list[Trajectory], t0: float, h: float) -> Trajectory:
    """One trajectory from consecutive chunks (each later chunk's first row is the join).

    The times are those of one call, :math:`t_0 + k h` (a chunk's own
    :math:`t_K + j h` differs from it in the last bit).
    """
    if len(parts) == 1:
        return parts[0]
    head, rest = parts[0], parts[1:]

    def joined(name):
        return np.concatenate([getattr(head, name)] + [getattr(p, name)[1:] for p in rest])

    reduced = None
    if head.q_reduced is not None:
        reduced = np.concatenate([head.q_reduced] + [p.q_reduced[1:] for p in rest])
    t = joined("t")
    variations = head.variations
    if variations is not None:
        variations = variations.joined([p.variations for p in parts])
    return replace(
        head,
        variations=variations,
        t=t0 + np.round((t - t0) / h) * h,
        q=joined("q"),
        p=joined("p"),
        q_reduced=reduced,
        newton_iterations=np.concatenate([p.newton_iterations for p in parts]),
        total_newton_iterations=sum(p.total_newton_iterations for p in parts),
        n_steps=sum(p.n_steps for p in parts),
        max_residual=max(p.max_residual for p in parts),
        kernel_path=", then ".join(dict.fromkeys(p.kernel_path for p in parts if p.kernel_path))
        or None,
    )


def _multiple(steps: int, save_every: int) -> int:
    """``steps`` rounded up to a multiple of ``save_every`` (chunks join at saved rows)."""
    return -(-steps // save_every) * save_every
