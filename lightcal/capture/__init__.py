"""From photographs to a project: what is computed when the images are taken.

One module a step (file formats stay in `lightcal.io`):

- `boards`: calibration boards (ArUco grid, ChArUco, chessboard), their geometry on the
  wall and their printable images (`lightcal.io.board_file` reads and writes them), with
  `chessboard` and `board_layout` (what the boards share);
- `plane_texture`: synthetic images of a printed texture on the wall, and look-at poses;
- `intrinsics`: camera intrinsics from views of a board (`lightcal camera calibrate`);
  `view_variety` says whether the views can determine them;
- `marker_pose`: a camera pose, with its covariance, from the markers in one image:
  `marker_detection` finds them, `pose_fit` fits the pose and its covariance;
- `colmap_align`: COLMAP poses (`lightcal.io.colmap`) moved into the wall's frame, metres;
- `project_init`: a project file from a folder of wall photographs (`lightcal init`):
  `init_checks` checks its arguments and each marker fit, `exif_exposures` makes the
  exposure entries, `mask_staging` keeps the masks aside until the project is written.

Frames and units: docs/conventions.md.
"""
