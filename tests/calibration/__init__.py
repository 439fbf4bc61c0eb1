"""Tests of the calibration layer: file format, undistortion, chessboard calibration, CLI."""
