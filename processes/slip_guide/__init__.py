"""A long-horizon guide planner: Bartlett & Manchester's SLIP footstep planner (centroidal
point-mass motion and footholds by reweighted l1 over candidate surface points), LCM-free.

``params`` (SlipParams), ``model`` (eqs. (1)-(2)), ``candidates`` (RKNN candidates, the
friction-cone prefilter, the cost map), ``planner`` (Problem 2, Algorithm 1), ``phases``
(Section III-E).
"""

from processes.slip_guide.candidates import Candidates, CostMap, sample_footholds
from processes.slip_guide.params import SlipParams
from processes.slip_guide.phases import Step, assign_phases
from processes.slip_guide.planner import SlipPlan, SlipPlanner, reference_path

__all__ = ["Candidates", "CostMap", "SlipParams", "SlipPlan", "SlipPlanner", "Step",
           "assign_phases", "reference_path", "sample_footholds"]
