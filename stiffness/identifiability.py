"""Which parameters a campaign can determine at all, whatever the noise.

A parameter is *unidentifiable* when its column of the weighted Jacobian (d deflection / d theta over
the measured components, `identify.jacobian`) lies in the span of the others, so that some change of
it, alone or with others, leaves every measured deflection unchanged. Example: with a laser tracker
(TCP position only) and the TCP on joint 6's axis, joint 6's axial compliance moves nothing measured.

Test. Scale each column to unit norm (Jn = J D^-1) and take the singular value decomposition
Jn = U S V^T. The right singular vectors v with s < IDENT_TOL s_max span the directions the data
cannot see; parameter k takes part in them when sum_v v_k^2 > PARTICIPATION. The fit keeps those
directions at the starting values (minimum-norm step, `identify.solve_ls`), and their standard
error is infinite.
"""

from __future__ import annotations

import numpy as np

IDENT_TOL = 1e-6        # singular value ratio below which a direction is not seen
PARTICIPATION = 1e-3    # share of a parameter in the unseen directions that makes it unidentifiable


def unidentifiable(Jw: np.ndarray) -> np.ndarray:
    """Boolean (P,): the parameters the weighted Jacobian ``Jw`` (n, P) cannot determine."""
    norms = np.linalg.norm(Jw, axis=0)
    dead = norms <= 1e-12 * max(float(norms.max(initial=0.0)), 1e-300)
    out = dead.copy()
    live = np.nonzero(~dead)[0]
    if len(live):
        Jn = Jw[:, live] / norms[live]
        wide = Jn.shape[0] < Jn.shape[1]          # fewer residuals than parameters
        _, s, Vt = np.linalg.svd(Jn, full_matrices=wide)
        s = np.concatenate([s, np.zeros(len(Vt) - len(s))])
        null = s < IDENT_TOL * s[0]
        out[live] = np.sum(Vt[null] ** 2, axis=0) > PARTICIPATION
    return out
