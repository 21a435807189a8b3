"""Stand-ins for the explicit pairs' stage sums, with what each computes: the joined module
has instead the straight-line source ``dop853_tableau.loop_source()`` and
``dopri5_tableau.loop_source()`` write out from their tableaus."""


def _dop853_stages(ks, t0, y0, h, K, ytmp, p, n):
    """Stages 2 … 12 from (t0, y0) into K[1 … 11]; ytmp ends as stage 12's y."""
    raise NotImplementedError


def _dop853_dense_stages(ks, t0, y0, h, K, ytmp, p, n):
    """Stages 14 … 16 (dense output only) into K[13 … 15]."""
    raise NotImplementedError


def _dop853_increment(K, i):
    """(Σ b_j k_j, Σ E5_j k_j, Σ E3_j k_j) of component i."""
    raise NotImplementedError


def _dop853_dense_sums(K, i):
    """Σ_j D[r][j] k_j of component i, r = 0 … 3."""
    raise NotImplementedError


def _dopri5_stages(ks, t0, y0, h, K, ytmp, p, n):
    """Stages 2 … 6 from (t0, y0) into K[1 … 5]; ytmp ends as stage 6's y."""
    raise NotImplementedError


def _dopri5_increment(K, i):
    """(Σ b_j k_j, Σ_{j<7} E_j k_j, 0) of component i."""
    raise NotImplementedError


def _dopri5_error_fsal(K, i):
    """E_7 k_7 of component i (k_7: f at the new point)."""
    raise NotImplementedError


def _dopri5_dense_sum(K, i):
    """Σ_j D_j k_j of component i."""
    raise NotImplementedError
