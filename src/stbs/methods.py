"""The method names, listed once.

This module imports nothing, so any module (a command's parser included) may take the
lists from here without loading the maths behind them.

- :data:`SKINNING_METHODS`: the four skinning methods (DESIGN §3): ``lbs`` (eq. 1-3),
  ``dqs`` (Kavan et al. 2008), ``stbs-lbs`` (eq. 5) and ``stbs-dqs`` (eq. 6).
- :data:`BONE_METHODS`: bone weights, bounded biharmonic (``bbw``) or bone heat (``heat``).
- :data:`ENDPOINT_METHODS`: endpoint weights (paper §2.2-2.3), the default first.
"""

SKINNING_METHODS = ("lbs", "dqs", "stbs-lbs", "stbs-dqs")
BONE_METHODS = ("bbw", "heat")
ENDPOINT_METHODS = ("bbw", "bbw-joints", "heat", "projection", "idw")

__all__ = ["SKINNING_METHODS", "BONE_METHODS", "ENDPOINT_METHODS"]
