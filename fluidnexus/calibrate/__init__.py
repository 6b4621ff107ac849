"""Camera import and calibration: PINF/NeRF/COLMAP importers, structure-from-motion, single-video rigs."""
