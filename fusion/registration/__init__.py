"""Online sensor registration: estimation of each radar's systematic errors (azimuth
offset, range offset, range gain, time-stamping offset) from the targets that two or
more radars see, with a reference radar or set of radars, and their correction in the
plot conversion (docs/concepts/registration.md).

Method (see :mod:`.bias_filter`, :mod:`.common_target`): pairs of plots of one track
from two radars give residuals linear in the biases (Fischer, Muehe & Cameron 1980;
Okello & Ristic 2003); a Kalman filter / recursive least squares on the stacked bias
vector, i.e. the recursive form of the linearised exact-ML registration (Zhou, Leung &
Yip 1997). Modules: ``config`` (RegistrationConfig, RegistrationMode), ``common_target``
(pairing and residuals), ``bias_filter`` (the filter), ``estimator``
(RegistrationEstimator), ``tracker_link`` (observe_tracker_output).
"""

from .config import RegistrationConfig, RegistrationMode
from .estimator import BiasEstimate, RegistrationEstimator
from .tracker_link import observe_tracker_output

__all__ = [
    "BiasEstimate",
    "RegistrationConfig",
    "RegistrationEstimator",
    "RegistrationMode",
    "observe_tracker_output",
]
