"""External validation of the force model: published bone-drilling thrust and torque, nobody here fitted them.

:mod:`~drillgym.eval.external.studies` holds the measurements as facts with their sources;
:mod:`~drillgym.eval.external.validate` runs the force model on their conditions after one calibration per
series and reports the rest as predictions (``drillgym validate-forces``; docs/external-validation.md).
"""
