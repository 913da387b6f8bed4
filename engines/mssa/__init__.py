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
``inverse_kinematics`` with the bridged observed angles as the reference (twist about
single-child bones and leaf rotations come from it), so bone lengths are the
skeleton's. ``fit`` learns the bases of both spaces and saves both.

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

Root: the root's position and orientation are passed through (gaps linearly bridged):
the trajectory is not stationary (a walk drifts metres, the heading unwraps without
bound), so short-window bases learned from other takes do not describe it, and the
angle corruptions leave it clean, as the paper assumes. Noise that reaches the root
(joint-position noise solved back to angles, the ``spatial`` corruption) is therefore
kept in angle mode; ``space="positions"`` handles it, since IK recovers the root's
orientation from the cleaned positions of its children.

Output: ``output="motion"`` (default) returns the minimiser z of Eq. 11, as the paper
does; with lambda = 0.1 and M = 20 it keeps about a fifth of whatever the bases cannot
explain, so some high-frequency noise remains. ``output="reconstruction"`` returns, at
each frame, the mean of the covering windows' basis reconstructions E c_s: smoother.

Diagnostics: ``robust_weight`` (F, C), the final data weight of every entry of the
filtered layout (the channel matrix (F, 3 + 3J) for angles, root-relative positions
(F, 3J) for positions): exp(-r^2 / p^2), near 1 for trusted samples and near 0 for the
samples treated as outliers, 0 where missing; 1 (observed) or 0 (missing) on the
channels not filtered (root, held channels).

Speed: the coefficient update and the overlap-add of the reconstructions are applied
together as one multichannel FIR filter (a matrix product over all frames, exact at the
ends; see :mod:`.solver`), the motion update is element-wise.
"""

from .engine import MSSA

__all__ = ["MSSA"]
