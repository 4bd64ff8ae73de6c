"""The sensor models of docs/model.md, as the codes the kernels take.

A pixel's value is offset + gain * sum_lights scale * sum_k weight_k Phi_k, with the
sensor weight of its quads k

- ``radiance`` (`SENSOR_RADIANCE`): 1 / A, A the footprint's area;
- ``cos4`` (`SENSOR_COS4`): cos^4(alpha) / A, alpha the angle between the optical axis
  and the ray through the mean of the pixel's undistorted corners;
- ``map`` (`SENSOR_MAP`): V(u, v) / A, V a per-pixel fall-off map;
- ``paper`` (`SENSOR_PAPER`): cos(theta_v) / d^2 per quad, d the distance from the
  quad's centroid to the camera centre, theta_v the viewing angle.
"""

from __future__ import annotations

SENSOR_RADIANCE = 0
SENSOR_COS4 = 1
SENSOR_PAPER = 2
SENSOR_MAP = 3
