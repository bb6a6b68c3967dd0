"""EKF-SLAM feature tracking with batch (graph) data association (paper section 2).

Each batch observation (the trees of one laser scan) is associated with the map as a
whole: by the maximum clique of the correspondence graph between the observation's
features and the predicted map features (relative geometry, Bailey et al. 2000), checked
by a joint compatibility gate; compared with nearest neighbour and JCBB on the Victoria
Park data set, and on one's own data as a landmark log in plain text
(:func:`read_landmark_log`, measured against its ground truth by ``run_slam``).

>>> from scanclique import slam
>>> model = slam.Ackermann(wheelbase=2.83, encoder_offset=0.76, laser_a=3.78, laser_b=0.5)
>>> model.laser_a
3.78
"""

from .association import (
    METHODS,
    NEW,
    REJECTED,
    Association,
    AssociationConfig,
    associate,
    point_distance_invariants,
)
from .ekf import SlamConfig, SlamResult, ekf_slam
from .models import Ackermann, MotionModel, Unicycle, controls_from_odometry, wrap
from .reader import (
    LandmarkLog,
    Step,
    read_gps,
    read_landmark_log,
    read_victoria_park,
    resolve_victoria_park,
    steps_from_arrays,
)

__all__ = [
    "METHODS",
    "NEW",
    "REJECTED",
    "Association",
    "AssociationConfig",
    "associate",
    "point_distance_invariants",
    "SlamConfig",
    "SlamResult",
    "ekf_slam",
    "Ackermann",
    "MotionModel",
    "Unicycle",
    "controls_from_odometry",
    "wrap",
    "LandmarkLog",
    "Step",
    "read_gps",
    "read_landmark_log",
    "read_victoria_park",
    "resolve_victoria_park",
    "steps_from_arrays",
]
