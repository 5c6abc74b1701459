"""A run, stage by stage: plan (:mod:`.plan`), start (:mod:`.start`), the frozen run
description and one compiled call (:mod:`.spec`, :mod:`.segment`), chunks (:mod:`.chunks`),
trust and failure policy (:mod:`.trust`, :mod:`.failures`), dense output, events and
requested rows (:mod:`.dense`, :mod:`.piecewise`, :mod:`.events`, :mod:`.outputs`), and the
drivers that put them together (:mod:`.smooth`, :mod:`.stream`, :mod:`.ensemble`).

The front doors (:class:`~galerkin_vi.Integrator`, :class:`~galerkin_vi.AdaptiveIntegrator`)
and the contact driver (:mod:`galerkin_vi.contact`) call these stages through their public
functions. :class:`~galerkin_vi.Integrator` checks its settings in :mod:`.options`, reads
the system's point functions through :mod:`.points` and routes each call to its run spec
and driver in :mod:`.dispatch`.
"""
