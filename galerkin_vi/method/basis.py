r"""Lagrange basis on control nodes, evaluated in barycentric form.

For control nodes :math:`d_0 < d_1 < \dots < d_s` the Lagrange basis is

.. math::

    \ell_\nu(x) = \prod_{\mu \ne \nu} \frac{x - d_\mu}{d_\nu - d_\mu},
    \qquad \ell_\nu(d_j) = \delta_{\nu j},

with barycentric weights :math:`w_\nu = 1/\prod_{\mu \ne \nu}(d_\nu - d_\mu)` [1]_.
The formulas used (theory.md §1):

* for :math:`x` in :math:`[d_0, d_s]` but not a node, the second (true) barycentric form

  .. math::

      \ell_\nu(x) = \frac{w_\nu / (x - d_\nu)}{\sum_\mu w_\mu / (x - d_\mu)},

  which sums to 1 up to rounding;
* for :math:`x` outside :math:`[d_0, d_s]` (extrapolation, as in the initial guess of the
  Newton iteration), the first form :math:`\ell_\nu(x) = w_\nu \prod_{\mu\ne\nu}(x - d_\mu)`.
  The second form cancels catastrophically there: at degree 20 it loses 11 digits at
  :math:`x = 1.5`, while the first form is backward stable everywhere [2]_;
* derivatives away from the nodes:
  :math:`\ell_\nu'(x) = \ell_\nu(x) \sum_{\mu \ne \nu} (x - d_\mu)^{-1}`, with the sum formed
  from prefix and suffix sums so that the excluded term is never subtracted;
* at a node :math:`x = d_j`: :math:`\ell_\nu(d_j) = \delta_{\nu j}` exactly,
  :math:`\ell_\nu'(d_j) = (w_\nu/w_j)/(d_j - d_\nu)` for :math:`\nu \ne j` and
  :math:`\ell_j'(d_j) = -\sum_{\nu \ne j} \ell_\nu'(d_j)`.

:func:`lagrange_tables` evaluates the same formulas in mpmath and rounds once; the integrator
builds its method tables with it.

References
----------
.. [1] J.-P. Berrut, L. N. Trefethen, "Barycentric Lagrange interpolation", SIAM Review 46
   (2004) 501–517.
.. [2] N. J. Higham, "The numerical stability of barycentric Lagrange interpolation",
   IMA J. Numer. Anal. 24 (2004) 547–556.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import mpmath
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .quadrature import gauss_lobatto, gauss_lobatto_mp, require_int

# 1/_TINY is the largest finite float64, so 1/(x - d) is finite whenever |x - d| >= _TINY.
_TINY = 1.0 / np.finfo(np.float64).max

__all__ = [
    "LagrangeBasis",
    "equidistant_control_nodes",
    "equidistant_control_nodes_mp",
    "lagrange_tables",
    "lagrange_tables_mp",
    "lobatto_control_nodes",
    "lobatto_control_nodes_mp",
]


def _validate_nodes(nodes: ArrayLike) -> NDArray[np.float64]:
    """Return the nodes as a new float64 array after checking them."""
    arr = np.array(nodes, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"nodes must be a one-dimensional array, got shape {arr.shape}")
    if arr.size < 2:
        raise ValueError(f"at least 2 nodes are required, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("nodes must be finite")
    if np.any(np.diff(arr) <= 0.0):
        raise ValueError("nodes must be strictly increasing")
    return arr


def _as_points(x: ArrayLike) -> NDArray[np.float64]:
    """Return evaluation points as a 1-D float64 array (a scalar becomes one point)."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    elif arr.ndim != 1:
        raise ValueError(f"x must be a scalar or a one-dimensional array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("x must be finite")
    return arr


def _exclusive_sums(a: NDArray[np.float64]) -> NDArray[np.float64]:
    r"""Row-wise :math:`\sum_{\mu \ne \nu} a_{i\mu}` for every :math:`\nu`, without subtraction."""
    out = np.zeros_like(a)
    out[:, 1:] = np.cumsum(a[:, :-1], axis=1)
    out[:, :-1] += np.cumsum(a[:, :0:-1], axis=1)[:, ::-1]
    return out


def _exclusive_products(a: NDArray[np.float64]) -> NDArray[np.float64]:
    r"""Row-wise :math:`\prod_{\mu \ne \nu} a_{i\mu}` for every :math:`\nu`, without division."""
    out = np.ones_like(a)
    out[:, 1:] = np.cumprod(a[:, :-1], axis=1)
    out[:, :-1] *= np.cumprod(a[:, :0:-1], axis=1)[:, ::-1]
    return out


@dataclass(frozen=True, eq=False, slots=True)
class LagrangeBasis:
    r"""Lagrange basis :math:`\ell_0, \dots, \ell_s` on control nodes :math:`d_0 < \dots < d_s`.

    Parameters
    ----------
    nodes : array_like, shape (s + 1,)
        Control nodes: finite, strictly increasing, at least two.  Stored as a read-only
        float64 copy.  Any interval is allowed; the Galerkin method uses nodes on
        :math:`[0, 1]` with both end points.

    Attributes
    ----------
    degree : int
        Polynomial degree :math:`s` = ``len(nodes) - 1``.
    barycentric_weights : ndarray, shape (s + 1,)
        :math:`w_\nu = 1/\prod_{\mu \ne \nu}(d_\nu - d_\mu)` (read-only, not rescaled).

    Raises
    ------
    ValueError
        If the nodes are not one-dimensional, fewer than two, not finite or not strictly
        increasing, or so many that the barycentric weights overflow float64.

    Examples
    --------
    >>> basis = LagrangeBasis([0.0, 0.5, 1.0])
    >>> basis.values([0.25])
    array([[ 0.375,  0.75 , -0.125]])
    >>> basis.differentiation_matrix()
    array([[-3.,  4., -1.],
           [-1.,  0.,  1.],
           [ 1., -4.,  3.]])
    """

    nodes: NDArray[np.float64]
    barycentric_weights: NDArray[np.float64] = field(init=False, repr=False)
    _differentiation_matrix: NDArray[np.float64] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Validate the nodes; compute the barycentric weights and differentiation matrix."""
        nodes = _validate_nodes(self.nodes)
        diff = nodes[:, None] - nodes[None, :]
        np.fill_diagonal(diff, 1.0)
        with np.errstate(over="ignore", under="ignore", divide="ignore"):
            weights = 1.0 / np.prod(diff, axis=1)
        if not np.all(np.isfinite(weights) & (weights != 0.0)):
            raise ValueError(
                f"the barycentric weights of these {nodes.size} nodes overflow float64; "
                "use fewer nodes"
            )
        # D[j, nu] = (w_nu / w_j) / (d_j - d_nu) off the diagonal; the diagonal is minus the
        # off-diagonal row sum, so that D annihilates constants to rounding error.
        dmat = (weights[None, :] / weights[:, None]) / diff
        np.fill_diagonal(dmat, 0.0)
        np.fill_diagonal(dmat, 0.0 - dmat.sum(axis=1))  # 0.0 - : no -0.0
        for array in (nodes, weights, dmat):
            array.setflags(write=False)
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "barycentric_weights", weights)
        object.__setattr__(self, "_differentiation_matrix", dmat)

    @property
    def degree(self) -> int:
        """Polynomial degree :math:`s` (number of nodes minus one)."""
        return int(self.nodes.size) - 1

    def values(self, x: ArrayLike) -> NDArray[np.float64]:
        r"""Basis values :math:`\ell_\nu(x_i)`.

        Parameters
        ----------
        x : float or array_like, shape (n,)
            Finite evaluation points; a scalar is treated as one point.  Points outside
            :math:`[d_0, d_s]` are allowed (extrapolation).

        Returns
        -------
        ndarray, shape (n, s + 1)
            ``out[i, nu]`` = :math:`\ell_\nu(x_i)`.  Rows at a node :math:`x_i = d_j` are exactly
            the unit vector :math:`e_j`.

        Raises
        ------
        ValueError
            If ``x`` has more than one dimension or is not finite.
        """
        return self._evaluate(_as_points(x), with_derivatives=False)[0]

    def derivatives(self, x: ArrayLike) -> NDArray[np.float64]:
        r"""Basis derivatives :math:`\ell_\nu'(x_i)`.

        Parameters
        ----------
        x : float or array_like, shape (n,)
            Finite evaluation points; a scalar is treated as one point.

        Returns
        -------
        ndarray, shape (n, s + 1)
            ``out[i, nu]`` = :math:`\ell_\nu'(x_i)`.  At a node :math:`x_i = d_j` the row is row
            :math:`j` of :meth:`differentiation_matrix`.

        Raises
        ------
        ValueError
            If ``x`` has more than one dimension or is not finite.
        """
        return self._evaluate(_as_points(x), with_derivatives=True)[1]

    def differentiation_matrix(self) -> NDArray[np.float64]:
        r"""Return the derivatives at the nodes, :math:`D_{j\nu} = \ell_\nu'(d_j)`.

        .. math::

            D_{j\nu} = \frac{w_\nu / w_j}{d_j - d_\nu} \quad (\nu \ne j), \qquad
            D_{jj} = -\sum_{\nu \ne j} D_{j\nu}.

        Returns
        -------
        ndarray, shape (s + 1, s + 1)
            A new array; row :math:`j` belongs to node :math:`d_j`.  For nodal values
            :math:`f_\nu = p(d_\nu)` of a polynomial :math:`p` of degree at most :math:`s`,
            ``D @ f`` gives :math:`p'(d_j)`.
        """
        return self._differentiation_matrix.copy()

    def _evaluate(
        self, x: NDArray[np.float64], *, with_derivatives: bool
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Values (and derivatives) at validated points ``x``; see the module docstring."""
        d, w = self.nodes, self.barycentric_weights
        diff = x[:, None] - d[None, :]
        # Nodes, and points so close to one (< 1/realmax ~ 5.6e-309) that 1/(x - d) would
        # overflow: to double precision their values and derivatives are those at the node.
        at_node = np.any(np.abs(diff) < _TINY, axis=1)
        inside = ~at_node & (x > d[0]) & (x < d[-1])
        outside = ~at_node & ~inside
        vals = np.empty_like(diff)
        if np.any(inside):
            # Second form; weights scaled by max |w| (it cancels) so the terms cannot overflow.
            terms = (w / np.max(np.abs(w))) / diff[inside]
            vals[inside] = terms / terms.sum(axis=1, keepdims=True)
        if np.any(outside):
            vals[outside] = w * _exclusive_products(diff[outside])
        nearest = np.argmin(np.abs(diff[at_node]), axis=1)
        vals[at_node] = np.eye(d.size)[nearest]
        if not with_derivatives:
            return vals, None
        ders = np.empty_like(diff)
        off = ~at_node
        ders[off] = vals[off] * _exclusive_sums(1.0 / diff[off])
        ders[at_node] = self._differentiation_matrix[nearest]
        return vals, ders


def lobatto_control_nodes(degree: int) -> NDArray[np.float64]:
    r"""Gauss–Lobatto–Legendre control nodes on :math:`[0, 1]`: ``gauss_lobatto(degree + 1).nodes``.

    Parameters
    ----------
    degree : int
        Polynomial degree :math:`s \ge 1`.

    Returns
    -------
    ndarray, shape (degree + 1,)
        Read-only; first node exactly 0.0, last exactly 1.0, exactly symmetric about 1/2.

    Examples
    --------
    >>> lobatto_control_nodes(2)
    array([0. , 0.5, 1. ])
    """
    return gauss_lobatto(require_int(degree, "degree", 1) + 1).nodes


def equidistant_control_nodes(degree: int) -> NDArray[np.float64]:
    r"""Equidistant control nodes :math:`d_\nu = \nu/s` on :math:`[0, 1]`.

    Each node is the correctly rounded :math:`\nu/s`, which can differ from
    ``np.linspace(0, 1, degree + 1)`` in the last bit.  It equals the float64 rounding of
    :func:`equidistant_control_nodes_mp`.

    Parameters
    ----------
    degree : int
        Polynomial degree :math:`s \ge 1`.

    Returns
    -------
    ndarray, shape (degree + 1,)
        A new array with first node 0.0 and last node 1.0.

    Examples
    --------
    >>> equidistant_control_nodes(4)
    array([0.  , 0.25, 0.5 , 0.75, 1.  ])
    """
    degree = require_int(degree, "degree", 1)
    return np.arange(degree + 1, dtype=np.float64) / degree


def lobatto_control_nodes_mp(degree: int, dps: int = 40) -> list[mpmath.mpf]:
    r"""Gauss–Lobatto–Legendre control nodes in mpmath: ``gauss_lobatto_mp(degree + 1, dps)[0]``.

    Parameters
    ----------
    degree : int
        Polynomial degree :math:`s \ge 1`.
    dps : int, optional
        Significant decimal digits (default 40).

    Returns
    -------
    list of mpmath.mpf, length degree + 1
        The very numbers of the Lobatto rule's nodes, so that :func:`lagrange_tables` sees
        exact coincidences with the collocated quadrature.
    """
    return gauss_lobatto_mp(require_int(degree, "degree", 1) + 1, dps)[0]


def equidistant_control_nodes_mp(degree: int, dps: int = 40) -> list[mpmath.mpf]:
    r"""Equidistant control nodes :math:`\nu/s` in mpmath, rounded to ``dps`` digits.

    Parameters
    ----------
    degree : int
        Polynomial degree :math:`s \ge 1`.
    dps : int, optional
        Significant decimal digits (default 40), :math:`\ge 1`.

    Returns
    -------
    list of mpmath.mpf, length degree + 1
    """
    degree = require_int(degree, "degree", 1)
    dps = require_int(dps, "dps", 1)
    with mpmath.workdps(dps):
        return [mpmath.mpf(nu) / degree for nu in range(degree + 1)]


def _mp_list(values: Iterable[object], name: str) -> list[mpmath.mpf]:
    """Convert to mpf at the current precision; floats and ints convert exactly if dps >= 15."""
    out = [mpmath.mpf(v) for v in values]
    if not all(mpmath.isfinite(v) for v in out):
        raise ValueError(f"{name} must be finite")
    return out


def _mp_exclusive(values: Sequence[mpmath.mpf], *, product: bool) -> list[mpmath.mpf]:
    """Exclusive prefix/suffix sums or products of a list, without subtraction or division."""
    n = len(values)
    unit = mpmath.mpf(1) if product else mpmath.mpf(0)
    prefix, suffix = [unit] * n, [unit] * n
    for k in range(1, n):
        a, b = prefix[k - 1], values[k - 1]
        prefix[k] = a * b if product else a + b
        a, b = suffix[n - k], values[n - k]
        suffix[n - k - 1] = a * b if product else a + b
    return [p * s if product else p + s for p, s in zip(prefix, suffix, strict=True)]


def lagrange_tables(
    control_nodes_mp: Sequence[object], points_mp: Sequence[object], dps: int = 40
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r"""Basis values and derivatives at points, computed in mpmath and rounded once.

    .. math::

        \Phi_{i\nu} = \ell_\nu(c_i), \qquad D_{i\nu} = \ell_\nu'(c_i),

    with the formulas of the module docstring evaluated at ``dps`` significant digits.  A point
    equal (in mpmath) to a control node gets the exact unit row in :math:`\Phi` and the node row
    of the differentiation matrix in :math:`D`; so for collocated nodes (e.g. control nodes
    from :func:`lobatto_control_nodes_mp` and points from :func:`gauss_lobatto_mp`)
    :math:`\Phi` is exactly the identity.

    Parameters
    ----------
    control_nodes_mp : sequence of mpmath.mpf (or float, int, str), length s + 1
        Control nodes :math:`d_\nu`: finite, strictly increasing, at least two.
    points_mp : sequence of mpmath.mpf (or float, int, str), length r
        Finite evaluation points :math:`c_i`; points outside :math:`[d_0, d_s]` are allowed.
    dps : int, optional
        Working precision in significant decimal digits (default 40).  Inputs are converted
        at this precision, so floats convert exactly when ``dps >= 15``.

    Returns
    -------
    Phi : ndarray, shape (r, s + 1)
        Values; each row sums to 1 up to the final rounding.
    D : ndarray, shape (r, s + 1)
        Derivatives; each row sums to 0 up to the final rounding.

    Raises
    ------
    ValueError
        If the control nodes are fewer than two, not finite or not strictly increasing, or a
        point is not finite.
    TypeError
        If ``dps`` is not an int.

    Examples
    --------
    >>> Phi, D = lagrange_tables([0, 0.5, 1], [0.25, 1.0])
    >>> Phi
    array([[ 0.375,  0.75 , -0.125],
           [ 0.   ,  0.   ,  1.   ]])
    >>> D
    array([[-2.,  2.,  0.],
           [ 1., -4.,  3.]])
    """
    phi, der = lagrange_tables_mp(control_nodes_mp, points_mp, dps)
    return (
        np.array([[float(v) for v in row] for row in phi]).reshape(len(phi), -1),
        np.array([[float(v) for v in row] for row in der]).reshape(len(der), -1),
    )


def lagrange_tables_mp(
    control_nodes_mp: Sequence[object], points_mp: Sequence[object], dps: int = 40
) -> tuple[list[list[mpmath.mpf]], list[list[mpmath.mpf]]]:
    """The tables of :func:`lagrange_tables` as nested lists of mpmath numbers, unrounded.

    Used by the extended-precision order studies.
    """
    dps = require_int(dps, "dps", 1)
    with mpmath.workdps(dps):
        d = _mp_list(control_nodes_mp, "control nodes")
        c = _mp_list(points_mp, "points")
        n = len(d)
        if n < 2:
            raise ValueError(f"at least 2 control nodes are required, got {n}")
        if any(a >= b for a, b in zip(d, d[1:], strict=False)):
            raise ValueError("control nodes must be strictly increasing")
        w = [1 / mpmath.fprod(d[nu] - d[mu] for mu in range(n) if mu != nu) for nu in range(n)]
        phi: list[list[mpmath.mpf]] = []
        der: list[list[mpmath.mpf]] = []
        for x in c:
            delta = [x - dm for dm in d]
            hits = [j for j, v in enumerate(delta) if v == 0]
            if hits:
                j = hits[0]
                row = [(w[nu] / w[j]) / (d[j] - d[nu]) if nu != j else 0 for nu in range(n)]
                row[j] = -mpmath.fsum(row)
                vals = [mpmath.mpf(nu == j) for nu in range(n)]
                ders = row
            else:
                inv = [1 / v for v in delta]
                if d[0] < x < d[-1]:
                    terms = [wn * r for wn, r in zip(w, inv, strict=True)]
                    total = mpmath.fsum(terms)
                    vals = [t / total for t in terms]
                else:
                    prods = _mp_exclusive(delta, product=True)
                    vals = [wn * p for wn, p in zip(w, prods, strict=True)]
                sums = _mp_exclusive(inv, product=False)
                ders = [v * s for v, s in zip(vals, sums, strict=True)]
            phi.append([+v for v in vals])
            der.append([+v for v in ders])
    return phi, der
