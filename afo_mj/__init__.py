"""afo_mj: human walking in MuJoCo with a hydraulic ankle-foot orthosis.

Layout (data flows one way): ``afo_mj.hydraulics`` (pure fluid-power physics, no MuJoCo) →
devices assembled from components → the MuJoCo bridge and controllers → scenarios → analysis →
outputs.
"""

__version__ = "0.1.0"
