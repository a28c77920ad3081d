"""Compatibility: the names of the former ``gyro_rotor.analysis.checks`` module.

The analysis now lives in one module per concept (issue 13): :mod:`.samples`,
:mod:`.prediction`, :mod:`.modes`, :mod:`.decay`, :mod:`.verdict`, :mod:`.criteria`,
:mod:`.results`, :mod:`.analyzer`, :mod:`.session`, :mod:`.offline`.
"""

from gyro_rotor.analysis.analyzer import limit_blas_threads, RotorAnalyzer
from gyro_rotor.analysis.modes import identify_modes, ModeCheck
from gyro_rotor.analysis.offline import analyze_bag, BagAnalysis
from gyro_rotor.analysis.prediction import predict, PredictedMode, Prediction
from gyro_rotor.analysis.results import (ANALYSIS_FIELDS, ANALYSIS_LABEL, AnalysisResult,
                                         MODE_FIELDS, MODE_LABEL, MODE_STATUS, SegmentResult,
                                         SYNC_STATES, VERDICTS)
from gyro_rotor.analysis.samples import (energy_sample_fields, Sample, SamplePairer,
                                         samples_from_trajectory)
from gyro_rotor.analysis.session import AnalysisSession, scene_from_sim_doc

__all__ = ['RotorAnalyzer', 'Sample', 'SamplePairer', 'Prediction', 'PredictedMode',
           'ModeCheck', 'SegmentResult', 'AnalysisResult', 'predict', 'identify_modes',
           'ANALYSIS_FIELDS', 'ANALYSIS_LABEL', 'MODE_FIELDS', 'MODE_LABEL', 'VERDICTS',
           'MODE_STATUS', 'SYNC_STATES', 'energy_sample_fields',
           'samples_from_trajectory', 'scene_from_sim_doc', 'AnalysisSession',
           'analyze_bag', 'BagAnalysis', 'limit_blas_threads']
