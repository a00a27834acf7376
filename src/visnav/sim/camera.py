"""Camera and depth-camera rendering consistent with the published calibration.

A :class:`CameraSensor` renders one :class:`~visnav.description.gazebo.CameraSpec` from a
compiled MuJoCo model: RGB from MuJoCo's lit pass (shadows and reflections off)
and depth from the depth buffer, read back and linearised.

One pass or two. MuJoCo's lit pass draws every opaque geom with depth writes on, so
its depth buffer is the depth of the opaque scene, exactly what a segmentation pass
(flat colours, no lighting) leaves. The two differ only where the lit pass draws
something that is not geometry or hides geometry from the depth buffer: the skybox
(a textured cylinder at 0.7 of the far clip, with depth), transparent geoms (alpha
below 0.995, and planes seen from behind, drawn with depth writes off), geoms without
a segmentation id, and multisampling. A sensor that renders colour and depth therefore
reads both buffers from the one lit pass when none of these is in its frame (checked
per frame after the render: the skybox and multisampling from the model, transparency
from the flags MuJoCo sets on the scene's geoms), and renders the separate
segmentation pass for depth only when one is. The depth is then bit-identical to the
separate pass's (tests/sim/test_camera.py), at the cost of one render instead of two.

Geometry. MuJoCo cameras look along -z with y up; the MuJoCo camera sits at
the sensor's link and ``<pose>`` with that orientation, so the published data
follow the optical convention (x right, y down, z forward). The MuJoCo camera
uses explicit intrinsics (sensor size, focal length and principal point in
pixels), so the rendered image has exactly the published K, including any
principal point (visnav's default ``(width / 2, height / 2)``). With lens distortion,
an undistorted image is rendered on a larger canvas covering every distorted
pixel's ray and warped with ``cv2.remap``, so a 3-D point projected with K and
D (``cv2.projectPoints``) lands where it is drawn.

Colour noise (``<noise>`` on a camera) is gaussian in [0, 1] units, quantised to
the 8-bit levels; for 8-bit encodings each frame reads its samples from a seeded,
precomputed pool at a random offset (two saturating adds per frame, as cheap as a
copy), the way Gazebo's noise shader offsets a per-pixel hash each frame.

Depth noise is the plugin's ``<depth_noise>`` disparity model
(:mod:`visnav.sim.noise_models`: error growing with the square of the range), applied
to the valid pixels (the range check sees the true depth), so the depth image, the
point cloud and anything derived from them (laser scans) carry it.

Depth is the z coordinate in the optical frame: ``32FC1`` metres with NaN
outside the valid range, or ``16UC1`` millimetres with 0 there. Point clouds
are organized (height x width), in the optical frame, NaN where depth is
invalid, with ``rgb`` when colour is rendered.

Headless OpenGL: call :func:`select_gl_backend` (done by :class:`RenderContext`)
before the first renderer; it prefers EGL, falls back to OSMesa and raises
:class:`RenderingUnavailableError` naming the missing library and its Debian
package when neither is installed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import mujoco
import numpy as np
from numpy.typing import NDArray

from visnav.description.gazebo import CameraSpec, LensDistortion
from visnav.msgs.image import numpy_to_image
from visnav.msgs.pointcloud import dtype_to_fields
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import CameraInfo, Header, Image, PointCloud2, RegionOfInterest
from visnav.sim.errors import CameraSensorError
from visnav.sim.gl import RenderContext, RenderingUnavailableError, select_gl_backend
from visnav.sim.noise_models import apply_depth_noise, noisy_depth_in_range

if TYPE_CHECKING:
    from visnav.sim.rebind import IdMap

__all__ = [
    "CameraFrame",
    "CameraSensor",
    "RenderContext",
    "RenderLayout",
    "RenderingUnavailableError",
    "camera_info",
    "configure_mujoco_camera",
    "distort_normalized",
    "render_layout",
    "select_gl_backend",
    "undistort_normalized",
]

# depth_image_proc / PCL point layouts: x, y, z float32 (+ pad), rgb at byte 16.
_XYZ_DTYPE = np.dtype(
    {"names": ["x", "y", "z"], "formats": ["<f4"] * 3, "offsets": [0, 4, 8], "itemsize": 16}
)
_XYZRGB_DTYPE = np.dtype(
    {
        "names": ["x", "y", "z", "rgb"],
        "formats": ["<f4"] * 4,
        "offsets": [0, 4, 8, 16],
        "itemsize": 32,
    }
)
_CANVAS_LIMIT = 2.5  # max render canvas size / image size with lens distortion
_CANVAS_MARGIN = 2.0  # pixels of margin around the distorted image's rays
_FAR_PLANE_TOLERANCE = 1e-6  # relative: depths this close to the far clip are no return


# --------------------------------------------------------------------------- distortion


def distort_normalized(
    x: NDArray[np.float64], y: NDArray[np.float64], d: LensDistortion
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Apply plumb_bob distortion to normalized image coordinates (as OpenCV does)."""
    r2 = x * x + y * y
    radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3))
    xd = x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x)
    yd = y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y
    return xd, yd


def undistort_normalized(
    xd: NDArray[np.float64], yd: NDArray[np.float64], d: LensDistortion, *, iterations: int = 30
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Invert :func:`distort_normalized` with Newton's method.

    Returns:
        The undistorted x, y and the largest remaining residual (normalized units).
    """
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3))
        dradial = 2.0 * d.k1 + r2 * (4.0 * d.k2 + 6.0 * d.k3 * r2)
        fx = x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x) - xd
        fy = y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y - yd
        j11 = radial + dradial * x * x + 2.0 * d.p1 * y + 6.0 * d.p2 * x
        j12 = dradial * x * y + 2.0 * d.p1 * x + 2.0 * d.p2 * y
        j21 = dradial * x * y + 2.0 * d.p1 * x + 2.0 * d.p2 * y
        j22 = radial + dradial * y * y + 6.0 * d.p1 * y + 2.0 * d.p2 * x
        det = j11 * j22 - j12 * j21
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        x = x - (j22 * fx - j12 * fy) / det
        y = y - (j11 * fy - j21 * fx) / det
    xr, yr = distort_normalized(x, y, d)
    residual = float(np.nanmax(np.hypot(xr - xd, yr - yd))) if xd.size else 0.0
    return x, y, residual


@dataclass(frozen=True)
class RenderLayout:
    """The MuJoCo render canvas of a camera and, with distortion, its warp to the image.

    ``fx``, ``fy``, ``cx``, ``cy`` are the canvas intrinsics (pixel centres at
    integer coordinates). ``map_x``/``map_y`` (float32, image-shaped) give the
    canvas coordinates each image pixel samples; None without distortion.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    map_x: NDArray[np.float32] | None = None
    map_y: NDArray[np.float32] | None = None


def _pixel_rays(
    spec: CameraSpec, u: NDArray[np.float64], v: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Undistorted normalized ray coordinates (x/z, y/z) of image pixels (u, v)."""
    xd = (u - spec.cx) / spec.fx
    yd = (v - spec.cy) / spec.fy
    if spec.distortion.is_zero:
        return xd, yd
    x, y, residual = undistort_normalized(xd, yd, spec.distortion)
    if not residual < 1e-9:
        msg = (
            f"camera {spec.name!r}: lens distortion {spec.distortion.d} cannot be inverted over "
            f"the {spec.width}x{spec.height} image (residual {residual:.3g}); the coefficients "
            "fold the image. Fix: use smaller k1/k2/k3/p1/p2"
        )
        raise CameraSensorError(msg)
    return x, y


def render_layout(spec: CameraSpec, *, with_maps: bool = True) -> RenderLayout:
    """Return the render canvas (and remap tables) that reproduce ``spec``'s K and D.

    Args:
        spec: the camera.
        with_maps: compute the per-pixel remap tables (False: canvas only).
    """
    if spec.distortion.is_zero:
        return RenderLayout(spec.width, spec.height, spec.fx, spec.fy, spec.cx, spec.cy)
    w, h = spec.width, spec.height
    # The rays through the image border (pixel edges) bound the canvas.
    us = np.arange(-0.5, w, 0.5)
    vs = np.arange(-0.5, h, 0.5)
    border_u = np.concatenate([us, us, np.full(vs.size, -0.5), np.full(vs.size, w - 0.5)])
    border_v = np.concatenate([np.full(us.size, -0.5), np.full(us.size, h - 0.5), vs, vs])
    bx, by = _pixel_rays(spec, border_u, border_v)
    xmin, xmax = float(bx.min()), float(bx.max())
    ymin, ymax = float(by.min()), float(by.max())
    scale = min(
        1.0,
        (_CANVAS_LIMIT * w - 2 * _CANVAS_MARGIN) / (spec.fx * (xmax - xmin)),
        (_CANVAS_LIMIT * h - 2 * _CANVAS_MARGIN) / (spec.fy * (ymax - ymin)),
    )
    fx, fy = spec.fx * scale, spec.fy * scale
    cx = -xmin * fx + _CANVAS_MARGIN
    cy = -ymin * fy + _CANVAS_MARGIN
    width = math.ceil(fx * (xmax - xmin) + 2 * _CANVAS_MARGIN) + 1
    height = math.ceil(fy * (ymax - ymin) + 2 * _CANVAS_MARGIN) + 1
    if not with_maps:
        return RenderLayout(width, height, fx, fy, cx, cy)
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    x, y = _pixel_rays(spec, u, v)
    return RenderLayout(
        width, height, fx, fy, cx, cy,
        map_x=(fx * x + cx).astype(np.float32),
        map_y=(fy * y + cy).astype(np.float32),
    )  # fmt: skip


def configure_mujoco_camera(camera: Any, spec: CameraSpec) -> None:
    """Give a MuJoCo spec camera (``mjsCamera``) the intrinsics of ``spec``'s render canvas.

    The camera gets ``resolution`` and ``sensor_size`` equal to the canvas in
    pixels (one length unit per pixel), the focal length in pixels and the
    principal point offset that puts the optical axis at (cx, cy).
    """
    layout = render_layout(spec, with_maps=False)
    camera.resolution = [layout.width, layout.height]
    camera.sensor_size = [float(layout.width), float(layout.height)]
    camera.focal_length = [layout.fx, layout.fy]
    # MuJoCo's principal offset is measured from the canvas centre ((n - 1) / 2 in
    # pixel-centre coordinates), positive towards -u and -v (verified by the tests).
    camera.principal_length = [
        (layout.width - 1) / 2.0 - layout.cx,
        (layout.height - 1) / 2.0 - layout.cy,
    ]


# --------------------------------------------------------------------------- messages


def camera_info(spec: CameraSpec, header: Header) -> CameraInfo:
    """Return the ``CameraInfo`` gazebo_ros_camera publishes for ``spec``.

    plumb_bob with ``D = (k1, k2, p1, p2, k3)``, ``K`` from :meth:`CameraSpec.k`,
    ``R`` identity and ``P = [K | (-fx * hack_baseline, 0, 0)]``.
    """
    return CameraInfo(
        header=header,
        height=spec.height,
        width=spec.width,
        distortion_model="plumb_bob",
        d=np.array(spec.distortion.d, dtype=np.float64),
        k=np.array(spec.k(), dtype=np.float64),
        r=np.eye(3).reshape(-1),
        p=np.array(spec.p(), dtype=np.float64),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


@dataclass(frozen=True)
class CameraFrame:
    """One rendered frame: messages (None when not produced) and the raw arrays.

    ``color`` is the published image as an array (encoding's layout); ``depth``
    is float32 metres in the optical frame with NaN where invalid.
    """

    stamp_ns: int
    camera_info: CameraInfo
    image: Image | None = None
    depth_image: Image | None = None
    depth_camera_info: CameraInfo | None = None
    points: PointCloud2 | None = None
    color: NDArray[Any] | None = None
    depth: NDArray[np.float32] | None = None


_NOISE_POOL_ENCODINGS = ("rgb8", "bgr8", "mono8")


class _ImageNoise:
    """Seeded additive gaussian noise for 8-bit images at the cost of two saturating adds.

    Gazebo draws camera noise in a shader from a per-pixel hash of the pixel position
    and a random offset chosen each frame. Here a pool of ``2 * size`` samples of
    ``N(mean, stddev)`` (in [0, 1] units, quantised to 8-bit levels exactly as
    ``rint((value + noise) * 255)`` does for integer pixel values) is drawn once from
    the sensor's seeded generator; each frame reads ``size`` consecutive samples from
    a random offset. Every pixel's noise has the configured distribution; frames are
    not independent draws in the strict sense (two frames share samples shifted by
    the difference of their offsets).
    """

    def __init__(self, mean: float, stddev: float, size: int, rng: np.random.Generator) -> None:
        self.size = size
        self.rng = rng
        levels = np.rint(rng.normal(mean * 255.0, stddev * 255.0, 2 * size))
        levels = np.clip(levels, -255.0, 255.0)
        self._up = np.clip(levels, 0.0, 255.0).astype(np.uint8)
        self._down = np.clip(-levels, 0.0, 255.0).astype(np.uint8)

    def apply(self, image: NDArray[np.uint8]) -> None:
        """Add noise to a contiguous uint8 image in place (saturating at 0 and 255)."""
        offset = int(self.rng.integers(0, self.size + 1))
        up = self._up[offset : offset + self.size].reshape(image.shape)
        down = self._down[offset : offset + self.size].reshape(image.shape)
        # Each sample is either >= 0 (in `up`) or <= 0 (in `down`), so the two
        # saturating operations equal clip(image + noise, 0, 255) exactly.
        cv2.add(image, up, dst=image)
        cv2.subtract(image, down, dst=image)


def _wrap_image(array: NDArray[Any], encoding: str, header: Header) -> Image:
    """An ``Image`` whose ``data`` is a view of ``array`` (a fresh, native-order array).

    :func:`visnav.msgs.image.numpy_to_image` copies; the sensor's arrays are new
    each frame, so wrapping them saves a copy per image.
    """
    arr = np.ascontiguousarray(array)
    if arr.dtype.byteorder == ">":  # pragma: no cover - the sensor makes native arrays
        return numpy_to_image(arr, encoding, header=header)
    return Image(
        header=header,
        height=int(arr.shape[0]),
        width=int(arr.shape[1]),
        encoding=encoding,
        is_bigendian=0,
        step=int(arr.strides[0]),
        data=arr.reshape(-1).view(np.uint8),
    )


# --------------------------------------------------------------------------- sensor


class CameraSensor:
    """Renders a :class:`~visnav.description.gazebo.CameraSpec` from a compiled MuJoCo model.

    Args:
        model: the compiled model holding the camera (see
            :func:`visnav.sim.robot.add_robot_to_spec`).
        spec: the camera configuration.
        camera: the MuJoCo camera name or id.
        seed: seed of this sensor's noise generator.
        context: a shared :class:`RenderContext` (default: a new one).
        render_color: render the colour image (default: when the plugin publishes
            an image, or for a plain camera); depth sensors always render depth.

    Raises:
        RenderingUnavailableError: no headless OpenGL.
        CameraSensorError: the camera does not exist, or its MuJoCo intrinsics do not
            match ``spec`` (build it with :func:`configure_mujoco_camera`).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        spec: CameraSpec,
        *,
        camera: str | int,
        seed: int = 0,
        context: RenderContext | None = None,
        render_color: bool | None = None,
    ) -> None:
        cam_id = (
            camera
            if isinstance(camera, int)
            else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        )
        if not 0 <= cam_id < model.ncam:
            names = [model.camera(i).name for i in range(model.ncam)]
            msg = (
                f"MuJoCo camera {camera!r} does not exist (cameras: {names}). Fix: add the "
                "robot with add_robot_to_spec before compiling"
            )
            raise CameraSensorError(msg)
        self.spec = spec
        self.model = model
        self.camera_id = int(cam_id)
        self.layout = render_layout(spec)
        want = (self.layout.width, self.layout.height)
        have = tuple(int(v) for v in model.cam_resolution[cam_id])
        if have != want or model.cam_sensorsize[cam_id][1] == 0:
            msg = (
                f"MuJoCo camera {camera!r} has resolution {have} without matching intrinsics; "
                f"camera {spec.name!r} needs a {want} canvas. Fix: configure it with "
                "configure_mujoco_camera"
            )
            raise CameraSensorError(msg)
        self.render_color = (
            render_color
            if render_color is not None
            else (spec.kind == "camera" or spec.image_topic is not None)
        )
        self.render_depth = spec.kind == "depth"
        self._owns_context = context is None
        self.context = context or RenderContext(
            model, max_width=self.layout.width, max_height=self.layout.height
        )
        if (
            self.layout.width > self.context.max_width
            or self.layout.height > self.context.max_height
        ):
            msg = (
                f"camera {spec.name!r} renders {want} but the shared RenderContext holds at most "
                f"{(self.context.max_width, self.context.max_height)}. Fix: create the context "
                "with max_width/max_height covering every camera"
            )
            raise CameraSensorError(msg)
        # depth noise on ``seed``'s stream, colour noise on a stream of its own: which
        # outputs are made depends on who subscribes, and must not shift the other's noise
        self.rng = np.random.default_rng(seed)
        self._color_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
        self._noise: _ImageNoise | None = None
        if spec.noise.active and spec.encoding in _NOISE_POOL_ENCODINGS and self.render_color:
            channels = 1 if spec.encoding == "mono8" else 3
            size = spec.width * spec.height * channels
            self._noise = _ImageNoise(spec.noise.mean, spec.noise.stddev, size, self._color_rng)
        self._scene = mujoco.MjvScene(model, maxgeom=max(1000, 2 * model.ngeom + 100))
        self._option = mujoco.MjvOption()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = self.camera_id
        flags = self._scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        # The lit pass's depth buffer is the depth pass's unless a skybox or
        # multisampling is drawn (module docstring); transparency is checked per frame.
        skybox = bool(np.any(model.tex_type == int(mujoco.mjtTexture.mjTEXTURE_SKYBOX)))
        self._one_pass_possible = (
            self.render_color
            and self.render_depth
            and not (skybox and flags[mujoco.mjtRndFlag.mjRND_SKYBOX])
            and int(self.context.mjr.offSamples) == 0
        )
        self.depth_passes = 0  # frames whose depth needed the separate segmentation pass
        self._rect = mujoco.MjrRect(0, 0, self.layout.width, self.layout.height)
        shape = (self.layout.height, self.layout.width)
        self._rgb = np.empty((*shape, 3), dtype=np.uint8)
        self._zbuf = np.empty(shape, dtype=np.float32)
        u, v = np.meshgrid(
            np.arange(spec.width, dtype=np.float64), np.arange(spec.height, dtype=np.float64)
        )
        rx, ry = _pixel_rays(spec, u, v)
        self._rays = (rx.astype(np.float32), ry.astype(np.float32))

    def rebind(self, ids: IdMap) -> None:
        """Render the same camera of a recompiled model (in ``ids.render_context``)."""
        self.close()  # a context of its own is made again for the new model
        self._owns_context = ids.render_context is None
        w, h = self.layout.width, self.layout.height
        self.context = ids.render_context or RenderContext(ids.model, max_width=w, max_height=h)
        self.model, self.camera_id = ids.model, ids.camera(self.camera_id)
        flags = self._scene.flags.copy()
        self._scene = mujoco.MjvScene(self.model, maxgeom=max(1000, 2 * self.model.ngeom + 100))
        self._scene.flags[:] = flags
        self._camera.fixedcamid = self.camera_id

    def close(self) -> None:
        """Free the render context if this sensor created it."""
        if self._owns_context:
            self.context.close()

    # rendering ---------------------------------------------------------------

    def _render_passes(
        self, data: mujoco.MjData, *, color: bool = True, depth: bool = True
    ) -> tuple[NDArray[np.uint8] | None, NDArray[np.float32] | None]:
        want_color = self.render_color and color
        want_depth = self.render_depth and depth
        vis = self.model.vis.map
        extent = float(self.model.stat.extent)
        saved = (float(vis.znear), float(vis.zfar))
        vis.znear = self.spec.clip_near / extent
        vis.zfar = self.spec.clip_far / extent
        try:
            mujoco.mjv_updateScene(
                self.model,
                data,
                self._option,
                None,
                self._camera,
                mujoco.mjtCatBit.mjCAT_ALL,
                self._scene,
            )
            self.context.make_current()
            rgb = metric = None
            have_depth = False
            if want_color:
                mujoco.mjr_render(self._rect, self._scene, self.context.mjr)
                have_depth = (
                    want_depth and self._one_pass_possible and not self._transparent_in_scene()
                )
                zbuf = self._zbuf if have_depth else None
                mujoco.mjr_readPixels(self._rgb, zbuf, self._rect, self.context.mjr)
                rgb = self._rgb[::-1]
            if want_depth and not have_depth:
                self.depth_passes += 1
                flags = self._scene.flags
                saved_flags = (
                    flags[mujoco.mjtRndFlag.mjRND_SEGMENT],
                    flags[mujoco.mjtRndFlag.mjRND_IDCOLOR],
                )
                flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
                flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
                try:
                    mujoco.mjr_render(self._rect, self._scene, self.context.mjr)
                    mujoco.mjr_readPixels(None, self._zbuf, self._rect, self.context.mjr)
                finally:
                    flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = saved_flags[0]
                    flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = saved_flags[1]
            if want_depth:
                glcam = self._scene.camera[0]
                near = np.float32(glcam.frustum_near)
                far = np.float32(glcam.frustum_far)
                # Reversed-Z depth buffer (1 at near, 0 at far) back to metric z.
                # depth = f n / (z (f - n) + n), in float32 (relative error ~1e-7).
                metric = np.multiply(self._zbuf[::-1], far - near, dtype=np.float32)
                metric += near
                np.divide(far * near, metric, out=metric)
        finally:
            vis.znear, vis.zfar = saved
        return rgb, metric

    def _transparent_in_scene(self) -> bool:
        """True when the last lit pass drew a geom without depth (set by ``mjr_render``)."""
        scene = self._scene
        return any(g.transparent or g.segid < 0 for g in scene.geoms[: scene.ngeom])

    def _warp(self, image: NDArray[Any], *, nearest: bool) -> NDArray[Any]:
        if self.layout.map_x is None or self.layout.map_y is None:
            return image
        interp = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
        return cv2.remap(
            image,
            self.layout.map_x,
            self.layout.map_y,
            interp,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0,
        )

    def _color(self, rgb: NDArray[np.uint8]) -> NDArray[Any]:
        """The published colour array: a fresh array (it becomes the message's data)."""
        spec = self.spec
        if self.layout.map_x is not None:
            image = self._warp(rgb, nearest=False)
        else:
            image = np.array(rgb, order="C", copy=True)
        if spec.encoding.startswith("mono"):
            image = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        elif spec.encoding == "bgr8":
            image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
        if self._noise is not None:
            self._noise.apply(image)
            return image
        deep = spec.encoding in ("mono16", "rgb16")
        noise = spec.noise
        if noise.active:
            top = 65535.0 if deep else 255.0
            values = image.astype(np.float32) / np.float32(255.0)
            values += self._color_rng.normal(noise.mean, noise.stddev, size=values.shape).astype(
                np.float32
            )
            noisy: NDArray[Any] = np.clip(np.rint(values * top), 0, top)
            return noisy.astype(np.uint16 if deep else np.uint8)
        if deep:
            wide: NDArray[np.uint16] = image.astype(np.uint16) * np.uint16(257)
            return wide
        return image

    def _depth(self, depth: NDArray[np.float32]) -> NDArray[np.float32]:
        spec = self.spec
        out = self._warp(depth, nearest=True)  # a fresh array: modified in place
        lo, hi = spec.depth_range
        # The far plane comes back from the depth buffer a few float32 ulps either side of
        # clip far: a pixel there saw nothing, so it is no return (NaN), not a depth of
        # clip far (every pixel of a camera whose far clip is nearer than the scene).
        hi *= 1.0 - _FAR_PLANE_TOLERANCE
        if not spec.noise.active and out.flags.c_contiguous:
            noisy_depth_in_range(out, spec.depth_noise, self.rng, (lo, hi))  # one pass
            return out
        invalid = (out <= lo) | (out >= hi)
        if spec.noise.active:
            out += self.rng.normal(spec.noise.mean, spec.noise.stddev, size=out.shape).astype(
                np.float32
            )
        apply_depth_noise(out, spec.depth_noise, self.rng)
        out[invalid] = np.nan
        return out

    def _bgra(self, color: NDArray[Any]) -> NDArray[np.uint8]:
        """The published colour image as a fresh BGRA uint8 array (alpha to be set)."""
        encoding = self.spec.encoding
        eight_bit = (color >> 8).astype(np.uint8) if encoding in ("mono16", "rgb16") else color
        code = {
            "mono8": cv2.COLOR_GRAY2BGRA,
            "mono16": cv2.COLOR_GRAY2BGRA,
            "bgr8": cv2.COLOR_BGR2BGRA,
        }.get(encoding, cv2.COLOR_RGB2BGRA)
        out = cv2.cvtColor(np.ascontiguousarray(eight_bit), code)
        return np.asarray(out, dtype=np.uint8)

    def _cloud(
        self, metres: NDArray[np.float32], color: NDArray[Any] | None, header: Header
    ) -> PointCloud2:
        """Organized cloud in depth_image_proc / PCL layout, filled in one allocation."""
        bgra = None if color is None else self._bgra(color)
        dtype = _XYZ_DTYPE if bgra is None else _XYZRGB_DTYPE
        floats = dtype.itemsize // 4
        # One zeroed float32 block, a row per point (padding stays 0, so the bytes are
        # deterministic); columns x, y, z and, with colour, rgb at byte 16.
        block = np.zeros((metres.size, floats), dtype=np.float32)
        flat = metres.reshape(-1)
        np.multiply(self._rays[0].reshape(-1), flat, out=block[:, 0])
        np.multiply(self._rays[1].reshape(-1), flat, out=block[:, 1])
        block[:, 2] = flat
        if bgra is not None:
            bgra[..., 3] = 0  # ROS rgb: 0x00RRGGBB in a little-endian uint32
            block[:, 4] = bgra.reshape(-1, 4).view(np.float32).reshape(-1)
        cloud = block.view(np.uint8).reshape(-1)
        height, width = metres.shape
        return PointCloud2(
            header=header,
            height=height,
            width=width,
            fields=dtype_to_fields(dtype),
            is_bigendian=False,
            point_step=dtype.itemsize,
            row_step=dtype.itemsize * width,
            data=cloud,
            is_dense=bool(np.isfinite(metres).all()),
        )

    def render(
        self,
        data: mujoco.MjData,
        *,
        stamp_ns: int = 0,
        image: bool = True,
        depth: bool = True,
        points: bool = True,
    ) -> CameraFrame:
        """Render the current state of ``data`` into messages stamped ``stamp_ns``.

        ``image``, ``depth`` and ``points`` say which outputs are wanted (the plugin
        passes whether each topic has a subscriber): what is not wanted is not rendered
        or computed (a cloud with colour needs the colour pass; depth noise is drawn only
        when depth is rendered, colour noise only when colour is).

        Args:
            data: MuJoCo data of the sensor's model (after ``mj_forward``/``mj_step``).
            stamp_ns: the header stamp (sim time in integer nanoseconds).
            image: produce the colour image (when the sensor renders colour).
            depth: produce the depth image (depth sensors).
            points: produce the point cloud (depth sensors with ``pointcloud``).

        Returns:
            The frame: ``camera_info`` always; ``image`` when colour is rendered and
            depth image, depth camera info and points for a depth sensor, each only
            when wanted.
        """
        spec = self.spec
        header = Header(stamp=ns_to_time(stamp_ns), frame_id=spec.frame_id)
        info = camera_info(spec, header)
        points = points and spec.pointcloud and self.render_depth
        rgb, raw_depth = self._render_passes(data, color=image or points, depth=depth or points)
        color = image_msg = None
        if rgb is not None:
            color = self._color(rgb)
            image_msg = _wrap_image(color, spec.encoding, header) if image else None
        if raw_depth is None:
            return CameraFrame(stamp_ns, info, image=image_msg, color=color)
        metres = self._depth(raw_depth)
        depth_image = None
        if depth and spec.depth_encoding == "16UC1":
            mm = np.nan_to_num(np.rint(metres * 1000.0), nan=0.0)
            mm = np.where(mm > 65535.0, 0.0, mm)
            depth_image = _wrap_image(mm.astype(np.uint16), "16UC1", header)
        elif depth:
            depth_image = _wrap_image(metres, "32FC1", header)
        cloud = self._cloud(metres, color, header) if points else None
        return CameraFrame(
            stamp_ns,
            info,
            image=image_msg,
            depth_image=depth_image,
            depth_camera_info=info if depth else None,
            points=cloud,
            color=color,
            depth=metres,
        )
