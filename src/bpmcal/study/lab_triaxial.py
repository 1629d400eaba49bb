"""The former home of the lab triaxial table's reader: it lives in
:mod:`bpmcal.study.lab_data` (with the lab specimens table), which this module re-exports.
"""
from .lab_data import LAB_TRIAXIAL_COLUMNS, lab_triaxial_problems, load_lab_triaxial

__all__ = ["LAB_TRIAXIAL_COLUMNS", "lab_triaxial_problems", "load_lab_triaxial"]
