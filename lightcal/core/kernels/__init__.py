"""Compiled (numba) kernels of the energy-preserving renderer (the model of docs/model.md).

- `fastmath`: branch-free log, exp, cos^m and atan series (no libm calls: pixel loops
  vectorise) and the float-bits / FMA intrinsics;
- `solid_angle`: Van Oosterom-Strackee solid angles of triangles and footprint quads;
- `sensor`: the sensor-model codes, where pixel corners meet the wall, and the sensor
  weights (shared with `lightcal.core.footprint_kernels`);
- `quad_flux`: the flux of one footprint quad and of one pixel's quads (the plain quad
  loop, with gradients);
- `wall_gradients`: the vectorised gradient path of quads on the wall;
- `flux`: `flux_pixels`, any pixels for one light, with gradients (`render.shade`);
- `image`: `render_image_fused`, a whole image of a rig in one pass (`render.render_image`);
- `port_image`: `render_image_port_fused`, the same through the camera's flat port, on
  the port's corner lattice (`port_render.render_image_through_port`);
- `wall`: the wall's relative reflectance B (`lightcal.core.wall`): per pixel with the
  chain rule on a light's flux and gradients, and on whole images.
- `medium`: the medium's transmittance T (`lightcal.core.medium`): per pixel with the
  chain rule on a light's flux and gradients, and on whole images.
- `port_flux`: the light's flat port (`lightcal.core.light_port`, `light_port_flux`): the
  path solve per point and the flux of pixels lit through the port, with gradients.
- `port_water`: the light's port in water: the paths' water lengths and exits
  (`light_port.port_paths`) and the medium's attenuation of the flux lit through it.
- `port_veil`: the veil of a light behind its port (`lightcal.core.light_port_veil`): the
  refracted beam's single scattering along each pixel's ray, with gradients.

The RID enters every kernel as one record, `rid_eval.RIDData` (several lights' RIDs as
one `rid_stack.RIDStack`). `lightcal.core.render_reference` is the plain NumPy
implementation of the same model that the tests compare these kernels against;
`tests/kernel_reference.py` holds the plain compiled versions of the fast paths.
"""
