"""One noiseless modem ping through a simulator's survey sensor, for tests that set the
geometry by hand (imported as ``from ping_harness import fuse_one_ping``, as ``optional``)."""

from __future__ import annotations


def fuse_one_ping(sim, est, P, beacon_pos, beacon_vel=(0.0, 0.0, 0.0), P_after_predict=False):
    """Fuse one ping of beacon 0 at survey vehicle 0 of batch row 0, in place: the survey at
    rest where ``sim.state.s_pos`` has it, its estimate ``est`` (3,) with covariance ``P``
    (3, 3) (set again after the prediction step with ``P_after_predict``, else only before
    it), the beacon at ``beacon_pos`` moving at ``beacon_vel`` and navigating without error,
    the water at its nominal temperature, and a range without noise that is not lost, not an
    outlier and not NaN. Returns the sensor's ``FusionOutputs``."""
    st, c = sim.state, sim.config
    st.s_est[0, 0] = est
    st.s_vel_true[:] = st.s_vel_est[:] = 0.0
    st.s_P[0, 0] = P
    st.b_pos[0, 0] = beacon_pos
    st.b_vel[0, 0] = beacon_vel
    st.b_nav_err[:] = 0.0
    st.b_nav_var_m2[:] = 0.0
    st.temperature_c[:] = c.water_temperature_c
    draws = sim._cycle_draws(st.cycle)
    draws["acoustic_n"][:] = 0.0
    draws["acoustic_u"][:] = 1.0  # not lost, not an outlier, not NaN
    out = sim._predict_depth_gps(draws)
    st.s_est[0, 0] = est  # the prediction step moved nothing but P; keep it exact
    if P_after_predict:
        st.s_P[0, 0] = P
    sim.sensor.fuse(draws, out)
    return out
