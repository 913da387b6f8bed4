"""``mssa``: example-based motion denoising and gap filling (Lou and Chai 2010).

Method (:mod:`.bases`, :mod:`.solver`): filter bases are the leading eigenvectors of the
grand lag-covariance matrix of clean training motion (multichannel singular spectrum
analysis over windows of M = ``window_frames`` frames, §3.1), K of them keeping
``energy_kept`` of the energy. A take is cleaned by minimising the paper's Eq. 11/16,
a Welsch robust data term (scale ``welsch_p_std``) plus ``prior_weight`` times the
distance of every sliding window from its projection on the bases, by alternating
closed-form coefficient updates with per-entry IRLS motion updates (§3.4) until the
objective settles. Missing entries get zero data weight and are filled from the bases,
starting from linear interpolation (§3.5).

Channels. ``space="angles"`` (default) filters the joint-angle channels of every joint
but the root (``angle_columns``, degrees). The observation's angles are unwrapped over
time robustly (each sample within 180 degrees of the median of the three before it, so
an outlier cannot leave a spurious whole turn behind it) and its gaps bridged linearly;
the result goes back onto the observation's own angle branch. ``space="positions"``
filters root-relative joint positions (F, 3J) in file units, computed by forward
kinematics from that bridged observation; a position counts as observed where all its
joint's ancestors are. The cleaned positions go back to angles by
``inverse_kinematics`` with what :func:`workbench.engine.smoothing.ik_reference` keeps of the
observation, as ``cae`` does, so bone lengths are the skeleton's: the observed angles
smoothed by the ``kalman`` engine's smoother as the reference (twist about single-child
bones and leaf rotations come from it); joints whose children all lie within
``short_lever_cm`` (the hands and finger bases) kept at it, where a few mm of position
error turn the angle by tens of degrees (test split, 5 seeds, rms_angle_deg aimed ->
kept: angular:0.5 4.71 -> 3.79, +outliers:0.05 16.1 -> 10.6, spatial:1 2.29 -> 1.96;
mpjpe within 0.03 cm); and joints aimed at one descendant within ``angle_lever_cm``
(the feet, spine and neck) kept at it where they are observed, when the take's noise is
in the angles (test split, 2 seeds, before -> after: angular:0.5 3.48 -> 1.60 degrees,
mpjpe 1.231 -> 1.187 cm; gaps:0.01 2.11 -> 1.82; spatial:1 2.10 -> 2.19, mpjpe 0.579 ->
0.581, the cost of smoothing twist the spatial corruption keeps true). The angles of
this space stay behind those of ``space="angles"`` (1.19 degrees at angular:0.5); it is
the choice for joint-position noise (spatial:1: mpjpe 0.58 cm).
``fit`` learns the bases of both spaces and saves both.

Normalisation, per channel: u = (x - c) / s. The centre c is the take's own median of
the channel (each training clip's in fitting, the observation's when cleaning: robust to
outliers, and it removes the per-subject posture offsets, 10-30 degrees on CMU's hands,
that the training takes do not share with new performers); the scale s is the channel's
RMS deviation from those medians pooled over all training frames, floored at 1 degree or
1 cm, so every channel weighs alike in the covariance and ``welsch_p_std`` is in units
of the channel's typical within-take spread. Channels that never vary within a training
take (s <= 1e-6: on CMU the hip joints, the shoulders, and two of the three rotations of
each hand and index finger) are not modelled: the training data says they do not move,
so they are held at the take's median. A channel never observed in a take starts at its
training mean.

Root: the trajectory is not stationary (a walk drifts metres, the heading unwraps
without bound), so short-window bases learned from other takes do not describe it. The
root's position and orientation are smoothed instead by the ``kalman`` engine's
smoother at the noise levels it finds in them (:func:`workbench.engine.smoothing.smooth_observed`;
gaps bridged linearly): the angle corruptions leave the root clean, as the paper
assumes, and it passes almost unchanged, but joint-position noise solved back to
angles (``spatial``) reaches it, and in angle mode a noisy root orientation turns the
whole cleaned body (test split, ``spatial:1``: mpjpe 2.64 cm with the root passed
through, worse than the input's 1.83; 1.32 smoothed). ``space="positions"`` puts the
cleaned root-relative positions on the smoothed root position (the root 1.59 -> 0.48 cm
off under ``spatial:1``) and recovers the root's orientation from its children by IK.

Output: ``output="motion"`` (default) returns the minimiser z of Eq. 11, as the paper
does. ``output="reconstruction"`` returns, at each frame, the mean of the covering
windows' basis reconstructions E c_s (smoother, but it loses what the bases cannot
explain, also where the data are clean).

Defaults beyond the paper (its exact setting: ``mssa:adaptive=false,solver=alternating,
smoothness=0,refit_prior_weight=0,start_median_frames=1,prior_weight=0.1,
energy_kept=0.99``; ``energy_kept`` changes the bases, so that one needs ``workbench
train`` first):

* ``adaptive=True``: the noise std sigma_l of every channel is estimated from the
  observation itself as the ``kalman`` engine estimates it (median absolute second
  difference, :func:`workbench.engine.smoothing.measurement_variance`; outliers and gaps do not
  bias it). Samples are weighted by 1 / (sigma_l^2 + noise_floor^2) and
  the Welsch scale is ``welsch_p_sigma`` sqrt(sigma_l^2 + noise_floor^2). Clean data
  (gaps only) are then kept almost exactly and the gaps filled from the bases; heavy
  noise gets strong smoothing; the outlier threshold follows the noise level.
* ``solver="cg"``: every IRLS round minimises its quadratic majoriser of the same
  objective exactly, by preconditioned conjugate gradients, instead of the paper's
  alternating (Jacobi-like) updates, which crawl once lambda is large next to the data
  weight and stop far from the minimum (the objective's relative change falls below the
  tolerance long before).
* ``prior_weight=3``, ``energy_kept=0.999`` (K grows from ~150 to ~600 bases of the
  angle space's 1360 dimensions).
* ``smoothness=1``: the objective also holds the prior of the ``kalman`` engine's
  smoother, a per-channel second-difference penalty weighted by the smoothing ratio
  that engine would choose for the channel (:mod:`.solver`; solved exactly per channel
  inside the conjugate gradients' preconditioner, a banded Cholesky). The learned bases
  know which joints move together over 20 frames, the smoothness term how smooth each
  channel of this take is over its whole length; together they beat either alone on
  moderate and heavy noise and keep the jitter of the filtered motion low.
* ``refit_prior_weight=1``: once the robust iterations have settled which samples are
  outliers (under lambda 3, which makes them stand out), the motion is solved for once
  more with those weights fixed and lambda 1, which biases the kept samples less.
* ``start_median_frames=5``: the robust iterations start from a 5-frame running median
  of the observation instead of the observation itself. The Welsch objective is not
  convex; from the raw samples the first rounds take every outlier at face value.

They were chosen on validation clips of the train split only: bases fitted on subjects
02, 05 and 07, scored on subjects 03, 06 and 09 (first 360 frames of each take, seeds
0-1); rms_angle_deg for angular 0.1 / 0.5 / 0.9 / 0.5+outliers 0.05 / 0.5+outliers 0.15,
gap_mpjpe_cm for joints:2 / gaps:0.01:

====================================== ===== ===== ===== ===== ===== ===== =====
setting                                 0.1   0.5   0.9   o.05  o.15  j:2   g.01
====================================== ===== ===== ===== ===== ===== ===== =====
paper (0.99, lambda 0.1, alternating)   1.79  2.61  3.74  3.05  5.52  2.44  1.73
paper, output=reconstruction            2.31  2.83  3.68  3.05  5.37  2.98  2.16
adaptive, lambda 1, alternating         1.04  2.40  3.46  3.13  6.32  1.09  0.50
adaptive, lambda 1, 0.999, alternating  0.82  2.22  3.38  3.55  8.78  1.04  0.34
adaptive, lambda 1, 0.999, cg           0.76  1.97  3.04  2.56  5.10  1.03  0.30
adaptive, lambda 3, 0.999, cg (default) 0.74  1.94  2.94  2.12  3.68  1.10  0.35
adaptive, lambda 3, 0.99, cg            1.54  3.06  3.97  3.38  4.73  1.58  0.76
kalman (same clips)                     0.47  1.70  2.69  9.96  17.2  1.29  0.31
butterworth / gaussian                  0.88  1.87  2.95  5.45  10.4   -     -
lerp / spline                            -     -     -     -     -    1.27  0.36/0.39
====================================== ===== ===== ===== ===== ===== ===== =====

(The j:2 and g.01 columns above used an earlier ``gap_mpjpe_cm``, which scored the
joints whose angles were missing; it now scores the positions those angles move.) The
smoothness term and the refit, chosen on the same clips with the current metric:

========================================== ===== ===== ===== ===== ===== ===== =====
setting (adaptive, 0.999, cg)               0.1   0.5   0.9   o.05  o.15  j:2   g.01
========================================== ===== ===== ===== ===== ===== ===== =====
lambda 3, smoothness 0 (earlier default)    0.74  1.94  2.93  2.12  3.68  8.09  1.03
lambda 3, smoothness 1                      0.76  1.79  2.69  2.01  3.41  8.41  1.00
lambda 1, smoothness 1                      0.69  1.65  2.56  2.04  3.90  8.17  1.02
lambda 0.3, smoothness 1                    0.65  1.61  2.51  2.35  4.98  8.03  1.06
lambda 1, smoothness 0.5                    0.65  1.62  2.52  2.16  4.20  8.22  0.95
lambda 3, smoothness 1, refit 1             0.73  1.67  2.58  1.98  3.35  8.41  0.98
the same, median start 5 frames             0.73  1.67  2.58  1.96  3.22  8.38  0.98
the same, median start 9 frames             0.73  1.67  2.58  1.96  3.22  8.35  0.98
lambda 3, smoothness 1, refit 0.3           0.72  1.62  2.53  2.11  3.44  8.41  0.98
lambda 3, smoothness 1, refit 0.1           0.72  1.62  2.53  2.38  3.66  8.41  0.99
refit 1, median 5, ratio from sigma (dflt)  0.66  1.65  2.57  1.98  3.23  8.10  0.94
kalman                                      0.47  1.70  2.69  9.96  17.2  12.3  1.16
========================================== ===== ===== ===== ===== ===== ===== =====

"Ratio from sigma" (the default): the smoothness term's ratio lambda_l is chosen for the
channel's measured noise sigma_l^2, as the ``kalman`` engine chooses it; earlier it was
chosen for sigma_l^2 + noise_floor^2, the variance of the data weights, which at light
noise is several times the noise and smoothed too far. (The kalman row above is from the
earlier runs; rerun with the rest: 0.48 1.63 2.64 9.90 17.0 12.3 1.16.) A larger Welsch
scale then trades the outlier columns for the Gaussian ones (welsch_p_sigma 4: 0.64 1.62
2.53 2.05 3.72 8.14 0.94; 5: 0.60 1.61 2.52 2.20 4.58 8.13 0.94); 3 is kept.

At 0.1 no setting reaches ``kalman``: on these clips (and on the test split) the error is
dominated by a few finger and thumb channels whose captured angles jump by 100-180
degrees for a frame or a few (06_14's LThumb, 35_26's RightFingerBase; on the test
split also 16_46's LeftFingerBase, at -41 degrees in frames 8-10 between 11 and 15). A
robust filter takes such jumps for outliers, as it must when they are
(``outliers:...``); ``kalman`` follows them (a refit with lambda ~0, i.e. the Kalman
smoother with the outliers removed, still scores 0.64). Lambda 3 is kept for its outlier
rejection (o.15).

Diagnostics: ``robust_weight`` (F, C), the final data weight of every entry of the
filtered layout (the channel matrix (F, 3 + 3J) for angles, root-relative positions
(F, 3J) for positions): exp(-r^2 / p^2), near 1 for trusted samples and near 0 for the
samples treated as outliers, 0 where missing; 1 (observed) or 0 (missing) on the
channels not filtered (root, held channels).

Speed: a 1200-frame (10 s) take (train clip 02_05) takes 0.35-1.1 s with Gaussian noise
(angular 0.1-0.5), 0.5 s with gaps and 7 s with 15 % outliers (more IRLS rounds, each ~80
conjugate-gradient steps) on this machine. The
coefficient update and the overlap-add of the reconstructions are applied
together as one multichannel FIR filter (a matrix product over all frames, exact at the
ends; see :mod:`.solver`), the motion update is element-wise.
"""

from .engine import MSSA

__all__ = ["MSSA"]
