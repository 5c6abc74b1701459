"""The loops' calling convention (loops/abi.py) and an import that changes nothing outside.

``import galerkin_vi`` must leave numba's compiler as numba ships it: the
package's faster inliner and post-processor are installed only inside
:func:`galerkin_vi.loops.compiling` (the warm-up), and restored after.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import loops
from galerkin_vi.codegen.slots import POINT_SLOTS
from galerkin_vi.loops import abi, point, traits
from galerkin_vi.run.status import RunStatus, loop_status

q, v, x, y, vx, vy = sp.symbols("q v x y vx vy")

# numba's attributes the package's compile-time replacements touch, by dotted name
_NUMBA_ORIGINALS = textwrap.dedent(
    """
    import copy
    from numba.core import caching, inline_closurecall, ir, postproc
    from numba.core.registry import CPUDispatcher

    IMPL = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")

    def originals():
        return {
            "PostProcessor.run": postproc.PostProcessor.run,
            "FunctionIR.get_block_entry_vars": ir.FunctionIR.get_block_entry_vars,
            "InlineWorker.inline_ir": inline_closurecall.InlineWorker.inline_ir,
            "InlineWorker.run_untyped_passes": inline_closurecall.InlineWorker.run_untyped_passes,
            "inline_closurecall.copy": inline_closurecall.copy,
            # the dispatcher numba gives a user's njit (the loops' drivers are a subclass)
            "CPUDispatcher.compile": CPUDispatcher.compile,
            # numba's cache locators, by value: the list is changed in place
            "locators": tuple(IMPL._locator_classes),
        }

    def same(before, after):
        return {k: after[k] == before[k] if k == "locators" else after[k] is before[k]
                for k in before}
    """
)


def _python(script: str, env: dict | None = None) -> dict:
    """Run ``script`` in a fresh interpreter; the JSON it prints last."""
    done = subprocess.run(
        [sys.executable, "-c", _NUMBA_ORIGINALS + textwrap.dedent(script)],
        env=env or dict(os.environ),
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_import_leaves_numbas_compiler_untouched():
    result = _python(
        """
        import json
        before = originals()
        assert inline_closurecall.copy is copy
        import galerkin_vi
        print(json.dumps(same(before, originals())))
        """
    )
    assert result == dict.fromkeys(result, True) and len(result) == 7


def test_users_numba_code_compiles_with_numbas_originals_after_a_run():
    # during the user's compilation, numba's post-processor must be numba's own: a spy
    # wrapped around the original at import records that it (not a replacement) runs
    result = _python(
        """
        import json
        import numpy as np
        import sympy as sp
        from numba import njit
        before = originals()
        calls = []
        original_run = before["PostProcessor.run"]

        def spy(self, *args, **kwargs):
            calls.append(1)
            return original_run(self, *args, **kwargs)

        postproc.PostProcessor.run = spy
        import galerkin_vi as gvi

        q, v = sp.symbols("q v")
        system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
        traj = gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=5)
        assert traj.success
        still_spy = postproc.PostProcessor.run is spy
        calls.clear()

        @njit
        def user_sum(a):
            total = 0.0
            for value in a:
                total += value * value
            return total

        value = user_sum(np.arange(4.0))
        after = originals()
        print(json.dumps({
            "still_spy": still_spy, "spy_ran": len(calls) > 0, "value": value,
            "inline_ir": after["InlineWorker.inline_ir"] is before["InlineWorker.inline_ir"],
            "entry_vars": after["FunctionIR.get_block_entry_vars"]
            is before["FunctionIR.get_block_entry_vars"],
            "copy": after["inline_closurecall.copy"] is copy,
            "locators": after["locators"] == before["locators"],
        }))
        """
    )
    assert result == {
        "still_spy": True,
        "spy_ran": True,
        "value": 14.0,
        "inline_ir": True,
        "entry_vars": True,
        "copy": True,
        "locators": True,
    }


def _originals_after(runs: str) -> dict:
    """In a fresh interpreter: import galerkin_vi, execute ``runs``, then compile a user's
    own njit function; which of numba's compile-time attributes are still numba's own."""
    prologue = """
        import json
        import numpy as np
        import sympy as sp
        from numba import njit
        before = originals()
        import galerkin_vi as gvi
        """
    epilogue = """
        @njit
        def user_sum(a):
            total = 0.0
            for value in a:
                total += value * value
            return total

        value = user_sum(np.arange(4.0))
        same_now = same(before, originals())
        same_now["value"] = value == 14.0
        # numba's own dispatcher and pipeline for the user's function (the loops' drivers
        # carry a subclass and a pipeline with one more pass, on their own dispatchers)
        same_now["user_dispatcher"] = type(user_sum).__name__ == "CPUDispatcher"
        same_now["user_pipeline"] = user_sum.targetoptions.get("pipeline_class") is None
        print(json.dumps(same_now))
        """
    parts = (prologue, runs, epilogue)
    return _python("\n".join(textwrap.dedent(part) for part in parts))


def test_users_numba_code_compiles_with_numbas_originals_after_tangent_runs():
    # the tangent loops, their member loop, the adjoint's reverse pass and the generated
    # parameter derivatives load or compile as the time loops do: nothing stays installed
    result = _originals_after(
        """
        q, v, k = sp.symbols("q v k")
        system = gvi.LagrangianSystem(v**2 / 2 + k * sp.cos(q), [q], [v], params={k: 1.0})
        integrator = gvi.Integrator(system, gvi.Galerkin(2))
        traj = integrator.integrate([1.0], [0.0], h=0.1, n_steps=5, tangent=True,
                                    sensitivity=[k])
        many = integrator.integrate_many([[1.0], [0.5]], [[0.0], [0.1]], h=0.1, n_steps=5,
                                         tangent=True, workers=1)
        grad = gvi.gradient(integrator, q**2, [1.0], [0.0], h=0.1, n_steps=5)
        assert traj.success and grad.success and len(many) == 2
        """
    )
    assert result == dict.fromkeys(result, True) and len(result) == 10


def test_users_numba_code_compiles_with_numbas_originals_after_multibody_runs():
    # the constrained loop's band variant (a chain), a rigid body on a joint and a body
    # contact load or compile as the other loops do: nothing stays installed
    result = _originals_after(
        """
        from galerkin_vi.tools.warmup import _runs

        label, rods, method, _, q0, v0 = next(r for r in _runs() if r[0] == "constrained, banded")
        integrator = gvi.Integrator(rods, method)
        chain = integrator.integrate(q0, v0=v0, h=0.01, n_steps=5)
        assert chain.success and integrator.run_spec.band is not None
        ball = gvi.RigidBody("ball", mass=1.0, inertia=[0.4, 0.4, 0.4])
        mb = gvi.Multibody([ball], gravity=[0, 0, -9.81], contacts=[
            gvi.BodyContact(gvi.Sphere(ball, 0.1), gvi.Plane([0, 0, 1], 0.0), restitution=0.5)])
        q0, v0 = mb.state(positions={"ball": [0, 0, 0.2]}, angular_velocities={"ball": [0, 1, 0]})
        bounce = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.01,
                                                                      n_steps=30)
        assert bounce.success and len(bounce.impacts) >= 1
        """
    )
    assert result == dict.fromkeys(result, True) and len(result) == 10


def test_users_numba_code_compiles_with_numbas_originals_after_compiled_contact_steps():
    # the time-stepping contact loop and its single step (a ball landing with friction: a
    # first touch handed back to Python, then steps in the loop): nothing stays installed
    result = _originals_after(
        """
        x, y, vx, vy = sp.symbols("x y vx vy")
        ball = gvi.LagrangianSystem(
            (vx**2 + vy**2) / 2 - 9.81 * y, [x, y], [vx, vy],
            contacts=[gvi.Contact(y, friction=0.5, slip=[vx])],
        )
        run = gvi.Integrator(ball, gvi.Galerkin(1)).integrate(
            [0.0, 0.004], [0.5, -1.0], h=0.01, n_steps=5, contact_mode="time-stepping")
        assert run.success and run.contact_forces is not None
        """
    )
    assert result == dict.fromkeys(result, True) and len(result) == 10


def test_users_numba_code_compiles_with_numbas_originals_after_issue_30_runs():
    # a composition and its tangent loop, scatter-loop point functions of springs between
    # scattered pairs, and an adaptive run with the persistent fixed point: nothing stays
    result = _originals_after(
        """
        from galerkin_vi.problems import kepler

        orbit = kepler(0.6)
        composed = gvi.Integrator(orbit.system, gvi.Composition(6))
        assert composed.integrate(orbit.q0, orbit.v0, h=0.05, n_steps=5, tangent=True).success
        xs, ws = sp.symbols("x0:150"), sp.symbols("w0:150")
        ring = gvi.LagrangianSystem(
            sum(w**2 for w in ws) / 2
            - sum((xs[(3 * i + 1) % 150] - xs[i]) ** 4 / 4 for i in range(150)),
            list(xs), list(ws),
        )
        spring = gvi.Integrator(ring, gvi.Galerkin(2))
        assert "for _k in range" in spring.source
        assert spring.integrate(np.linspace(0, 1, 150), np.zeros(150), h=0.01, n_steps=3).success
        adaptive = gvi.AdaptiveIntegrator(orbit.system, gvi.Galerkin(3, gvi.gauss_legendre(3)))
        assert adaptive.integrate(orbit.q0, orbit.v0, h=0.1, n_steps=5).success
        """
    )
    assert result == dict.fromkeys(result, True) and len(result) == 10


def test_users_numba_code_compiles_with_numbas_originals_after_generated_loops():
    # the loops generated per system compile on first call, after their cache locator
    # was registered for their decoration only: nothing of it stays for the user's code
    result = _originals_after(
        """
        from galerkin_vi.problems import henon_heiles

        problem = henon_heiles()
        composed = gvi.Integrator(problem.system, gvi.Composition(6))
        assert composed.run_spec.explicit_steps is not None
        assert composed.integrate(problem.q0, problem.v0, h=0.05, n_steps=5).success
        gauss = gvi.Galerkin(2, gvi.gauss_legendre(2))
        staged = gvi.Integrator(problem.system, gauss, specialize="system")
        assert staged.run_spec.stage_steps is not None
        assert staged.integrate(problem.q0, problem.v0, h=0.05, n_steps=5).success
        """
    )
    assert result == dict.fromkeys(result, True) and len(result) == 10


def test_compiling_installs_its_replacements_only_inside_and_restores_them():
    from numba.core import inline_closurecall, ir, postproc

    def current():
        return (
            postproc.PostProcessor.run,
            ir.FunctionIR.get_block_entry_vars,
            inline_closurecall.InlineWorker.inline_ir,
            inline_closurecall.InlineWorker.run_untyped_passes,
            inline_closurecall.copy,
        )

    before = current()
    with loops.compiling():
        inside = current()
        with loops.compiling():  # nested: installed once
            assert current() == inside
        assert current() == inside
    assert all(a is not b for a, b in zip(before, inside, strict=True))
    assert all(a is b for a, b in zip(before, current(), strict=True))
    with pytest.raises(RuntimeError, match="boom"), loops.compiling():
        raise RuntimeError("boom")
    assert all(a is b for a, b in zip(before, current(), strict=True))


def test_switch_tests_on_data_arguments_are_folded_before_typing():
    # a switch that is data (an array, a tuple) is never None: its tests become constants
    # and numba's dead branch pruning drops the None branch, as it does for a None switch
    import operator

    from numba import njit
    from numba.core import compiler, ir, types

    from galerkin_vi.loops._jit import _LOOP_COMPILER, _never_none, fold_switch_tests

    def switched(pattern, couplings, n, m):
        if pattern is not None:
            n += 1
        if None is couplings:
            n += 2
        if m is None:  # a scalar argument: also never None (n, reassigned: left alone)
            n += 4
        return n

    args = (types.float64[:], types.none, types.int64, types.int64)
    func_ir = compiler.run_frontend(switched)
    assert fold_switch_tests(func_ir, args) == 2  # the test of None against None is numba's
    tests = [
        stmt.value
        for block in func_ir.blocks.values()
        for stmt in block.body
        if isinstance(stmt, ir.Assign)
        and isinstance(stmt.value, ir.Expr)
        and stmt.value.op == "binop"
        and stmt.value.fn in (operator.is_, operator.is_not)
    ]
    assert len(tests) == 1  # None is couplings: left to numba's own pruning
    assert _never_none(types.UniTuple(types.int64, 4)) and not _never_none(types.none)
    assert not _never_none(types.Optional(types.float64[:]))
    compiled = njit(switched, pipeline_class=_LOOP_COMPILER)
    assert compiled(np.zeros(1), None, 0, 0) == 3
    assert compiled(np.zeros(1), (True, False), 0, 0) == 1
    assert compiled(None, None, 0, 0) == 2


def test_unreadable_loop_cache_files_are_discarded_when_the_loops_are_made_ready(warm_cache):
    folder = next((warm_cache / "loops").iterdir())
    index = sorted(folder.glob("explicit.explicit_loop-*.nbi"))[0]
    index.write_bytes(index.read_bytes()[:10])  # a killed writer
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=str(warm_cache))
    result = _python(
        f"""
        import json, pathlib
        index = pathlib.Path({str(index)!r})
        import galerkin_vi
        after_import = index.exists()
        from galerkin_vi.loops.readiness import ensure_loops
        ensure_loops()
        print(json.dumps({{"after_import": after_import, "after_ready": index.exists()}}))
        """,
        env,
    )
    assert result == {"after_import": True, "after_ready": False}


def test_point_slots_are_one_table():
    assert sorted(POINT_SLOTS.values()) == list(range(abi.N_SLOTS))
    names = {
        "point_gradient": abi.GRADIENT,
        "point_hessian": abi.HESSIAN,
        "lagrangian": abi.LAGRANGIAN,
        "point_constraint": abi.CONSTRAINT,
        "point_constraint_jacobian": abi.CONSTRAINT_JAC,
        "point_constraint_rate": abi.CONSTRAINT_RATE,
        "point_constraint_hessian": abi.CONSTRAINT_HESS,
        "point_mass": abi.MASS,
        "point_velocity": abi.VELOCITY,
        "point_contact": abi.CONTACT,
        "point_slip": abi.SLIP,
    }
    assert names == POINT_SLOTS
    # the loops' modules read the same objects
    assert (point.GRADIENT, point.MASS, point.VELOCITY, point.N_SLOTS) == (
        abi.GRADIENT, abi.MASS, abi.VELOCITY, abi.N_SLOTS
    )  # fmt: skip
    assert (traits.BAND, traits.AUTONOMOUS, traits.N_TRAITS) == (abi.BAND, abi.AUTONOMOUS, 4)
    system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    addresses = integrator.compiled_point_functions(("point_gradient", "lagrangian"))[0]
    assert len(addresses) == abi.N_SLOTS
    assert addresses[abi.GRADIENT] != 0 and addresses[abi.LAGRANGIAN] != 0
    assert addresses[abi.CONSTRAINT] == 0  # no constraints: never compiled
    assert addresses[abi.CONTACT] == 0 and addresses[abi.SLIP] == 0


def test_status_codes_map_to_run_statuses():
    assert loop_status(abi.STATUS_OK) == RunStatus.COMPLETED
    assert loop_status(abi.STATUS_NEWTON_FAILED) == RunStatus.NO_CONVERGENCE
    assert loop_status(abi.STATUS_SINGULAR) == RunStatus.SINGULAR_JACOBIAN
    assert loop_status(abi.STATUS_NONFINITE) == RunStatus.NON_FINITE


@pytest.mark.parametrize("save_every", [1, 3])
def test_linear_loop_counts_one_iteration_per_step_itself(save_every):
    system = gvi.LagrangianSystem((vx**2 + vx * vy + vy**2) / 2 - (x**2 + y**2) / 2,
                                  [x, y], [vx, vy])  # fmt: skip
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    assert integrator.kernel_path == "linear"
    n_steps = 10
    q0, v0 = [0.5, -0.2], [0.1, 0.0]
    traj = integrator.integrate(q0, v0, h=0.1, n_steps=n_steps, save_every=save_every)
    assert traj.success and len(traj.t) == -(-n_steps // save_every) + 1
    assert traj.total_newton_iterations == n_steps
    assert list(traj.newton_iterations) == [1] * -(-n_steps // save_every)
    assert traj.max_residual == 0.0  # nothing iterates
    # an ensemble member runs the same compiled loop: the same counts, bit for bit the same rows
    many = integrator.integrate_many([q0] * 2, [v0] * 2, h=0.1, n_steps=n_steps,
                                     save_every=save_every)  # fmt: skip
    for member in many:
        assert member.total_newton_iterations == n_steps
        np.testing.assert_array_equal(member.newton_iterations, traj.newton_iterations)
        np.testing.assert_array_equal(member.q, traj.q)
        np.testing.assert_array_equal(member.p, traj.p)


def test_explicit_loop_reports_a_completed_run_without_iterations():
    system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
    integrator = gvi.Integrator(system, gvi.Galerkin(1))
    assert integrator.kernel_path == "explicit"
    traj = integrator.integrate([0.5], [0.1], h=0.1, n_steps=7)
    assert traj.success and len(traj.t) == 8
    assert traj.max_residual == 0.0 and traj.total_newton_iterations == 0


def test_loop_result_names_the_fields_in_order():
    result = abi.LoopResult(*range(len(abi.RESULT_FIELDS)))
    assert result._fields == abi.RESULT_FIELDS
