"""A run in chunks yielded one by one (:meth:`Integrator.stream`): memory bounded by a chunk."""

from __future__ import annotations

import numbers
from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConvergenceError
from .chunks import carry_turns
from .failures import check_failure_mode, failed_run
from .outputs import without_first_row
from .tangent import variation_request
from .trajectory import Trajectory

__all__ = ["check_stream_arguments", "checked_stream", "stream_chunks"]


def check_stream_arguments(n_steps, chunk_steps, save_every, on_failure) -> None:
    """The arguments of :meth:`Integrator.stream` that the chunks depend on, checked."""
    check_failure_mode(on_failure)
    if (
        isinstance(chunk_steps, bool)
        or not isinstance(chunk_steps, numbers.Integral)
        or chunk_steps < 1
    ):
        raise ValueError(f"chunk_steps must be a positive int, got {chunk_steps!r}")
    if not isinstance(save_every, numbers.Integral) or save_every < 1:
        raise ValueError(f"save_every must be a positive int, got {save_every!r}")
    if chunk_steps % save_every:
        raise ValueError(
            f"chunk_steps ({chunk_steps}) must be a multiple of save_every ({save_every}) "
            "for the chunks to save the rows one run would"
        )
    if isinstance(n_steps, bool) or not isinstance(n_steps, numbers.Integral) or n_steps < 0:
        raise ValueError(f"n_steps must be a non-negative int, got {n_steps!r}")


def checked_stream(
    integrate: Callable[..., Trajectory], system, q0: ArrayLike, v0, p0, *, h, n_steps,
    chunk_steps, t0, params, save_every, project: bool, on_failure: str, tangent=None,
    sensitivity=None,
) -> Iterator[Trajectory]:  # fmt: skip
    """:func:`stream_chunks` of :meth:`Integrator.stream`, its arguments checked first.

    ``stream_chunks`` is a generator, whose body runs only at the first ``next()``;
    checking here, when ``stream()`` is called, reports bad arguments at the call.
    ``system`` is the integrator's, against which ``tangent`` and ``sensitivity`` are
    checked.

    Raises
    ------
    ValueError
        For bad ``n_steps``, ``chunk_steps``, ``save_every``, ``on_failure``, ``tangent``
        or ``sensitivity``.
    """
    check_stream_arguments(n_steps, chunk_steps, save_every, on_failure)
    variation_request(system, tangent, sensitivity, 0)
    return stream_chunks(
        integrate, q0, v0, p0, h=h, n_steps=int(n_steps), chunk_steps=int(chunk_steps), t0=t0,
        params=params, save_every=save_every, project=project, on_failure=on_failure,
        tangent=tangent, sensitivity=sensitivity,
    )  # fmt: skip


def stream_chunks(
    integrate: Callable[..., Trajectory], q0: ArrayLike, v0, p0, *, h, n_steps: int,
    chunk_steps: int, t0, params, save_every: int, project: bool, on_failure: str,
    tangent=None, sensitivity=None,
) -> Iterator[Trajectory]:  # fmt: skip
    r"""The chunks of a run of ``n_steps``, each ``integrate(q, v0=, p0=, ...)`` of at most
    ``chunk_steps`` steps from where the last ended (see :meth:`Integrator.stream`).

    Every chunk after the first leaves out its first row (the previous chunk's last);
    angles continue across chunks from their reduced values, their whole turns added
    back. A failure is reported in the step count of the whole run. The tangent and
    the sensitivities carry across the joins: a later chunk starts from the frame
    :math:`[\Phi, S]` of the last row, and its sensitivities add its own
    (:math:`S = \Phi_{chunk} S_{join} + S_{chunk}`).
    """
    done = 0
    previous = None  # the last chunk yielded (its angles' whole turns carry to the next)
    start = {"v0": v0, "p0": p0}
    q_start: ArrayLike = q0
    t_start = float(t0)
    while previous is None or done < n_steps:
        first = previous is None
        steps = min(chunk_steps, n_steps - done)
        variations = {"tangent": tangent, "sensitivity": sensitivity}
        if not first and previous.variations is not None:
            variations = continued_variations(previous.variations, sensitivity)
        try:
            chunk = integrate(
                q_start, **start, h=h, n_steps=steps, t0=t_start, params=params,
                save_every=save_every, project=project and first, on_failure="raise",
                **variations,
            )  # fmt: skip
            if not first and previous.variations is not None:
                chunk = replace(chunk, variations=joined_variations(previous.variations,
                                                                    chunk.variations))  # fmt: skip
        except ConvergenceError as exc:
            exc.step += done
            partial = exc.partial if first else carry_turns(previous, exc.partial)
            partial = partial if first else without_first_row(partial)
            message = f"{partial.message} (step {exc.step} of the whole run)"
            exc.partial = replace(partial, message=message)
            if on_failure == "raise":
                raise
            yield failed_run(exc.partial, on_failure, step=exc.step, t=exc.t, residual=exc.residual)
            return
        chunk = chunk if first else carry_turns(previous, chunk)
        yield chunk if first else without_first_row(chunk)
        done += steps
        previous = chunk
        q_start = chunk.q_reduced[-1] if chunk.q_reduced is not None else chunk.q[-1]
        start = {"v0": None, "p0": chunk.p[-1]}
        t_start = float(t0) + done * h  # not chunk.t[-1]: no rounding accumulates


def continued_variations(last, sensitivity) -> dict:
    """The ``tangent`` and ``sensitivity`` arguments of the chunk after one whose
    variations are ``last``: the frame [Phi, S] of its last row as the directions."""
    parts = [part[-1] for part in (last.tangent, last.sensitivity) if part is not None]
    return {"tangent": np.hstack(parts), "sensitivity": sensitivity}


def joined_variations(last, new):
    """The variations of a chunk run from :func:`continued_variations`' frame, split
    back into the tangent and the accumulated sensitivities."""
    r = 0 if last.tangent is None else last.tangent.shape[2]
    frame = new.tangent
    tangent = frame[:, :, :r] if last.tangent is not None else None
    sensitivity = None
    if last.sensitivity is not None:
        sensitivity = frame[:, :, r:] + new.sensitivity
    return replace(new, tangent=tangent, sensitivity=sensitivity)
