"""Every tolerance and default of rblog, with its unit and what it trades off.

Numerical modules import from here; nothing else hard-codes a threshold.
"""

from __future__ import annotations

# --- integrators -----------------------------------------------------------------------------
#: Newton iterations of the polar decomposition R <- (R + R^-T)/2 stop when the largest entry of
#: the last update is below this (dimensionless). Newton converges quadratically, so the iterate
#: is then within ~POLAR_TOL^2 = 1e-16 (round-off) of orthonormal; a smaller value costs one more
#: iteration (~15 ns per body-step) and buys nothing.
POLAR_TOL = 1e-8
#: Cap on polar Newton iterations. Converges quadratically: from ||R^T R - I|| = 1e-4 it takes 2.
POLAR_MAX_ITER = 12

# --- run loop ---------------------------------------------------------------------------------
#: A run is split into blocks that each run in one compiled call; a block holds at most this many
#: logged samples (fewer blocks: less per-block work in the recorders) ...
BLOCK_MAX_SAMPLES = 4096
#: ... and at most this many body-samples, which bounds a block's memory whatever the body count:
#: ~420 bytes per body-sample (state and derived channels, float64) = ~14 MB per block; the run
#: holds at most ~4 blocks at once (stepping, queued, being written).
BLOCK_MAX_BODY_SAMPLES = 32_768
#: ... and at most this many body-steps, so that progress and Ctrl-C are seen every ~50 ms.
BLOCK_MAX_BODY_STEPS = 2_000_000
#: A progress bar is shown when the run is expected to last longer than this (seconds, wall).
PROGRESS_MIN_WALL_S = 1.0
#: Print a "compiling kernels" notice when the first compiled call has not returned by then (s).
COMPILE_NOTICE_AFTER_S = 0.4

# --- logging ----------------------------------------------------------------------------------
#: Default logging rate when neither --log-every nor --log-rate is given (samples per simulated
#: second). 100 Hz plays back smoothly in the viewers and resolves bounces at dt = 1e-3.
DEFAULT_LOG_RATE_HZ = 100.0

# --- scene validation -------------------------------------------------------------------------
#: Tolerance on |q| for a quaternion given in a scene: it is normalized, but one far from unit
#: length is probably a typo (a zero quaternion is rejected).
QUAT_MIN_NORM = 1e-9
