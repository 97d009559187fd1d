"""Reading a simulation: the metrics of a run (one traceable implementation) and the sensor
model that turns a simulated signal into what an instrument records."""

from .metrics import JOINT_METRIC_KEYS, RUN_METRIC_KEYS, joint_metrics, run_metrics, summary
from .sensor import Accelerometer
