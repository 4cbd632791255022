"""Which parameters a campaign can determine at all, whatever the noise.

A parameter is *unidentifiable* when its column of the weighted Jacobian (d deflection / d theta over
the measured components, `identify.jacobian`) lies in the span of the others, so that some change of
it, alone or with others, leaves every measured deflection unchanged. Example: with a laser tracker
(TCP position only) and the TCP on joint 6's axis, joint 6's axial compliance moves nothing measured.

Test. With F = J^T J the information (up to the noise), scale it to unit diagonal
(Fn = D^-1 F D^-1, D = sqrt(diag F)) and decompose Fn = V diag(lambda) V^T. The eigenvectors v with
lambda < IDENT_TOL^2 lambda_max (singular values of the scaled J below IDENT_TOL times the largest)
span the directions the data cannot see; parameter k takes part in them when sum_v v_k^2 >
PARTICIPATION. The fit keeps those directions at the starting values (minimum-norm step,
`identify.solve_ls`), and their standard error is infinite.
"""

from __future__ import annotations

import numpy as np

IDENT_TOL = 1e-6        # singular value ratio below which a direction is not seen
PARTICIPATION = 1e-3    # share of a parameter in the unseen directions that makes it unidentifiable


def unidentifiable(Jw: np.ndarray) -> np.ndarray:
    """Boolean (P,): the parameters the weighted Jacobian ``Jw`` (n, P) cannot determine."""
    return unidentifiable_information(Jw.T @ Jw)


def unidentifiable_information(F: np.ndarray) -> np.ndarray:
    """Boolean (P,): the parameters the information matrix ``F`` (P, P) = J^T J cannot determine."""
    d = np.sqrt(np.clip(np.diag(F), 0.0, None))
    dead = d <= 1e-12 * max(float(d.max(initial=0.0)), 1e-300)
    out = dead.copy()
    live = np.nonzero(~dead)[0]
    if len(live):
        Fn = F[np.ix_(live, live)] / np.outer(d[live], d[live])
        lam, V = np.linalg.eigh(Fn)
        null = lam < IDENT_TOL**2 * lam.max()
        out[live] = np.sum(V[:, null] ** 2, axis=1) > PARTICIPATION
    return out
