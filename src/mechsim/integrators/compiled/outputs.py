"""What the outputs read of a run besides the state: energy terms, invariants, observables
and frames at each sample, evaluated in one compiled call."""

from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def evaluate_outputs(ks, ts, Y, p, want_energy, want_inv, want_obs, want_frames,
                     E_out, I_out, O_out, F_out):
    """Energy terms, invariants, observables and frames at each sample, only those wanted."""
    for k in range(ts.size):
        if want_energy:
            ks.energy(ts[k], Y[k], p, E_out[k])
        if want_inv and ks.n_inv > 0:
            ks.invariants(ts[k], Y[k], p, I_out[k])
        if want_obs and ks.n_obs > 0:
            ks.observables(ts[k], Y[k], p, O_out[k])
        if want_frames and ks.n_frames > 0:
            ks.frames(ts[k], Y[k], p, F_out[k])
