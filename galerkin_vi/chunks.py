"""Long runs in chunks: a progress bar, and Ctrl-C that stops a compiled run.

A compiled loop does not return to Python until it is done, so a
KeyboardInterrupt waits for its end (a user pressed Ctrl-C at 8 s of a
5e7-step run; it took effect at 83.6 s and the result was lost). A run whose
first ``FIRST_CHUNK`` steps predict more than ``CHUNK_SECONDS`` of work is
therefore run in chunks of about ``CHUNK_SECONDS``: between them Python
updates the progress bar and sees Ctrl-C, which ends the run with the states
of the chunks completed (status ``INTERRUPTED``).

Each chunk continues from the state the previous one ended in, like
:meth:`Integrator.stream`: the result equals one call's up to round-off at
the joins (every chunk starts its iteration afresh and without the
compensation bits of the summed positions). Runs shorter than a chunk are
one call, as before.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .trajectory import Trajectory

__all__ = ["CHUNK_SECONDS", "FIRST_CHUNK", "MIN_CHUNK", "PROGRESS_AFTER", "run_in_chunks"]

#: work per chunk (seconds): the delay of Ctrl-C and of the progress bar
CHUNK_SECONDS = 0.5
#: steps of the first call, which measures the cost per step
FIRST_CHUNK = 5000
#: fewest steps of a later chunk (each chunk's cold start costs about one iteration)
MIN_CHUNK = 1000
#: runs predicted to take longer show a progress bar on a terminal (progress=None)
PROGRESS_AFTER = 2.0


def run_in_chunks(
    run: tuple, run_chunk: Callable, restart: Callable, progress: bool | None
) -> tuple[Trajectory, int, int, float, bool]:
    """Run ``run`` = (q0, p0, v0, t0, h, n_steps, save_every, prm) in timed chunks.

    Parameters
    ----------
    run_chunk : callable
        ``run_chunk(run) -> (trajectory, status, steps done, increment)``, one
        compiled call.
    restart : callable
        ``restart(q, p, t) -> (q0, p0, v0)``, the start of the next chunk.
    progress : bool or None
        Show a tqdm bar: always, never, or (None) when the run is predicted to
        take more than ``PROGRESS_AFTER`` seconds and stderr is a terminal.

    Returns
    -------
    trajectory, status, done, increment, interrupted
        As ``run_chunk`` for the whole run; ``interrupted`` when Ctrl-C
        ended it (the trajectory then holds the chunks completed).
    """
    q0, p0, v0, t0, h, n_steps, save_every, prm = run
    first = min(n_steps, _multiple(FIRST_CHUNK, save_every))
    start = time.perf_counter()
    traj, status, done, increment = run_chunk((q0, p0, v0, t0, h, first, save_every, prm))
    per_step = (time.perf_counter() - start) / max(first, 1)
    left = n_steps - first
    if status != 0 or left == 0:
        return traj, status, done, increment, False
    # a rest shorter than a chunk is one more call (chunk >= left below)
    return _continue(traj, [traj], run, first, left, run_chunk, restart, progress, per_step)


def _continue(traj, parts, run, done_steps, left, run_chunk, restart, progress, per_step):
    """The chunks after the first, stitched to it."""
    _, _, _, t0, h, n_steps, save_every, prm = run
    chunk = _multiple(max(MIN_CHUNK, int(CHUNK_SECONDS / max(per_step, 1e-12))), save_every)
    if progress is None:
        progress = per_step * left > PROGRESS_AFTER and sys.stderr.isatty()
    bar = _bar(n_steps, done_steps) if progress else None
    status, increment, interrupted = 0, np.nan, False
    last = traj
    try:
        while left > 0:
            steps = min(chunk, left)
            q_start = last.q_reduced[-1] if last.q_reduced is not None else last.q[-1]
            t_start = t0 + done_steps * h  # not last.t[-1]: no rounding accumulates
            q, p, v = restart(q_start, last.p[-1], t_start)
            part, status, done, increment = run_chunk((q, p, v, t_start, h, steps, save_every, prm))
            if last.q_reduced is not None:
                # whole turns of the angles, carried from one chunk to the next
                part = replace(part, q=part.q + (last.q[-1] - last.q_reduced[-1]))
            parts.append(part)
            last = part
            if bar is not None:
                bar.update(done)
            if status != 0:
                done_steps += done
                break
            done_steps += steps
            left -= steps
    except KeyboardInterrupt:
        interrupted = True
    finally:
        if bar is not None:
            bar.close()
    return _stitched(parts, t0, h), status, done_steps, increment, interrupted


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
    return replace(
        head,
        t=t0 + np.round((t - t0) / h) * h,
        q=joined("q"),
        p=joined("p"),
        q_reduced=reduced,
        newton_iterations=np.concatenate([p.newton_iterations for p in parts]),
        total_newton_iterations=sum(p.total_newton_iterations for p in parts),
        n_steps=sum(p.n_steps for p in parts),
        max_residual=max(p.max_residual for p in parts),
    )


def _multiple(steps: int, save_every: int) -> int:
    """``steps`` rounded up to a multiple of ``save_every`` (chunks join at saved rows)."""
    return -(-steps // save_every) * save_every


def _bar(total: int, done: int):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=done, unit="step", unit_scale=True, leave=False)
