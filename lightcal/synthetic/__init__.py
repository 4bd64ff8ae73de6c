"""Synthetic calibration data with known ground truth (`lightcal synth`, tests, benchmarks).

- `scenes`: numbers in memory: camera views, light rigs, the sensor's noise and clipping;
- `dataset`: a dataset folder on disk (images, camera, light, project and truth files).

Frames and units: docs/conventions.md; the model the images follow: docs/model.md.
"""
