"""Synthetic calibration data with known ground truth (`lightcal synth`, tests, benchmarks).

- `scenes`: numbers in memory, gathered from `views` (camera poses), `rigs` (lights and
  their RIDs) and `sensor` (noise and clipping), with `sampling` (checks, random vectors);
- `dataset`: a dataset folder on disk (images, camera, light, project and truth files),
  with `dataset_files` (the folder's layout and the contents of its files).

Frames and units: docs/conventions.md; the model the images follow: docs/model.md.
"""
