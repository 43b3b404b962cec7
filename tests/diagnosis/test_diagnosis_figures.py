"""The diagnosis's figures draw without warnings on little data."""

import warnings

import numpy as np

from drillgym.eval.diagnosis.channels import LF_CHANNELS
from drillgym.eval.diagnosis.figures import plot_spectra


def test_spectra_of_residuals_too_short_for_a_spectrum_draw_without_a_legend_warning(tmp_path):
    short = {"real − nominal": np.zeros((20, len(LF_CHANNELS))), "null − nominal": np.zeros((20, len(LF_CHANNELS)))}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plot_spectra(short, tmp_path / "spectra.png")
    assert (tmp_path / "spectra.png").stat().st_size > 0
