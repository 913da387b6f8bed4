"""``mssa``: example-based motion denoising and gap filling (Lou and Chai 2010).

Method (:mod:`.bases`, :mod:`.solver`): filter bases are the leading eigenvectors of the grand
lag-covariance matrix of clean training motion (multichannel singular spectrum analysis over windows
of M = ``window_frames`` frames, §3.1), K of them keeping ``energy_kept`` of the energy. A take is
cleaned by minimising the paper's Eq. 11/16, a Welsch robust data term (scale ``welsch_p_std``, §3.2)
plus ``prior_weight`` times the distance of every sliding window from its projection on the bases, by
closed-form coefficient updates and per-entry IRLS motion updates (§3.4) until the objective settles.
Missing entries get zero data weight and are filled from the bases, from linear interpolation (§3.5).

Channels: ``space="angles"`` (default) filters the joint-angle channels (degrees) of every joint but
the root, unwrapped robustly (so an outlier leaves no whole turn behind), back on the observation's
own branch. ``"positions"`` filters root-relative joint positions (F, 3J), file units, from FK of the
bridged observation (observed where all the joint's ancestors are), and returns to angles by
``inverse_kinematics`` keeping and weighing what :func:`workbench.engine.smoothing.ik_reference` says,
as ``cae`` does (``short_lever_cm``, ``angle_lever_cm``). ``fit`` learns the bases of both spaces.

Per channel u = (x - c) / s: c the take's own median (robust to outliers, and it removes posture
offsets the training subjects do not share with new performers), s the RMS deviation from those
medians pooled over the training frames, floored at 1 degree or 1 cm. Channels that never vary within
a training take are held at the take's median; a channel never observed starts at its training mean.
The root is not stationary, so no short-window bases describe it: it is smoothed by the
constant-velocity smoother (:func:`workbench.engine.smoothing.smooth_observed`), as position noise reaches it.
``output="motion"`` returns the minimiser z of Eq. 11, as the paper does; ``"reconstruction"`` the
mean of the covering windows' E c_s. ``robust_weight`` (F, C): the final data weight exp(-r^2 / p^2)
of each filtered entry, 0 where missing, 1 or 0 on channels not filtered; in positions on the take's
own skeleton, ``raw_positions`` (F, J, 3), the filtered joint positions before IK (file units).

Beyond the paper (chosen on validation clips of the training subjects; its exact setting is
``mssa:adaptive=false,solver=alternating,smoothness=0,refit_prior_weight=0,start_median_frames=1,
prior_weight=0.1,energy_kept=0.99``, the last after ``workbench train``): ``adaptive``, each channel's
noise sigma from the observation (:func:`workbench.engine.smoothing.measurement_variance`), weights
1 / (sigma^2 + ``noise_floor``^2), Welsch scale ``welsch_p_sigma`` times its root, so clean data are
kept and the outlier threshold follows the noise; ``solver="cg"``, each IRLS round solved exactly
(the paper's alternating updates stop far from the minimum); ``prior_weight=3``,
``energy_kept=0.999``; ``smoothness=1``, the ``kalman`` smoother's prior added (better than either
term alone); ``refit_prior_weight=1``, a last solve at lambda 1 with the outliers fixed (biasing kept
samples less); ``start_median_frames=5``, a running-median start (the objective is not convex).

History and results: docs/engines/mssa.md.
"""

from .engine import MSSA

__all__ = ["MSSA"]
