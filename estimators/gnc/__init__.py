r"""Onboard guidance and control of the descent: ZEM/ZEV waypoint guidance in the rotating frame and a thruster model.

Description
-----------
The guidance and control blocks of the GN&C loop of C. A. Wright et al., "Relative Terrain Imaging Navigation
(RETINA) Tool for the Asteroid Redirect Robotic Mission (ARRM)", NASA GSFC, 2016 (Fig. 2): the navigation filter's
estimate [r, v] (asteroid-fixed frame) goes to the guidance law, whose commanded acceleration the thrusters
deliver with their own errors.

* :mod:`.zem_zev` — zero-effort-miss / zero-effort-velocity guidance (Guo, Hawkins & Wie 2013,
  doi:10.2514/1.58099; Ebrahimi, Bahrami & Roshanian 2008, doi:10.1016/j.actaastro.2008.01.011) through a list of
  waypoints: the zero-effort prediction carries the onboard point-mass gravity and the rotating frame's Coriolis
  and centrifugal terms (eq. G2), the command is the minimum-energy piecewise-constant control that meets the next
  waypoint's position and velocity, held over the control period (eq. G4; the continuous law G3 as the period
  goes to 0), and after the last waypoint the touchdown velocity is held until contact (G5).
* :mod:`.thrusters` — the delivered acceleration: thrust limit, minimum impulse bit (T1), magnitude error (bias +
  per-command, T2), pointing error (misalignment + per-command, T3), impulse and propellant bookkeeping; seeded.

Tuning
------
``control_period_s`` must equal the period the commands are really held for: G4 is the minimum-energy sequence of
holds of that length, correcting any error that enters up to two periods before the waypoint. ``gm_m3_s2`` is the onboard GM (the
truth's field, J2 or a polyhedron, differs: the feedback absorbs it, the prediction error shrinks with t_go).
``prediction_step_s`` (RK4 step of G2) of 20 s keeps the prediction error far below a millimetre over the descent's
segments (the slowest time scale is 1/ω ≈ 2000 s). ``max_accel_mps2`` is the thrust limit over the mass; a
saturated command is flagged in ``last.saturated``. Waypoints: 200 m (the start), 50 m spin-matched (zero velocity
in the rotating frame), optionally the profile's last constant-rate altitude, then the surface target with the
touchdown velocity — ``renderlab.studies.descent_gnc.waypoints.arrm_waypoints`` builds them from the ARRM profile.
Thrusters: a minimum impulse bit b limits the terminal velocity accuracy to about b/m (the smallest velocity change
a command can make); magnitude and pointing σ make the landing dispersion grow (Monte Carlo over seeds).

Use
---
``g = ZemZevGuidance(ZemZevOptions(waypoints=(Waypoint(t, r, v), ...), gm_m3_s2=μ, omega_rad_s=(0, 0, ω),
control_period_s=Δ))``; every Δ: ``a_cmd = g.command(t, x_est)``; ``a = thr.realise(a_cmd, Δ)`` with
``thr = ThrusterModel(ThrusterOptions(...), np.random.default_rng(seed))``; integrate the truth with ``a`` held.
The lab's contract adapter is ``renderlab.measurement.builtin_guidance.ZemZevLaw`` (registered guidance law
``zem_zev``, :data:`renderlab.plugins.guidance`).

References
----------
Y. Guo, M. Hawkins and B. Wie, "Applications of generalized zero-effort-miss/zero-effort-velocity feedback guidance
algorithm", J. Guidance, Control, and Dynamics 36(3), 2013, doi:10.2514/1.58099.

B. Ebrahimi, M. Bahrami and J. Roshanian, "Optimal sliding-mode guidance with terminal velocity constraint for
fixed-interval propulsive maneuvers", Acta Astronautica 62, 2008, doi:10.1016/j.actaastro.2008.01.011.

C. A. Wright et al., "Relative Terrain Imaging Navigation (RETINA) Tool for the Asteroid Redirect Robotic Mission
(ARRM)", NASA Goddard Space Flight Center, 2016 (the GN&C loop of its Fig. 2; a technical report, no DOI).
"""

from estimators.gnc.thrusters import ThrusterModel, ThrusterOptions
from estimators.gnc.zem_zev import GuidanceState, Waypoint, ZemZevGuidance, ZemZevOptions

__all__ = ["GuidanceState", "ThrusterModel", "ThrusterOptions", "Waypoint", "ZemZevGuidance", "ZemZevOptions"]
