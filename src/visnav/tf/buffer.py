"""The transform buffer: tf2's ``BufferCore`` semantics, rclpy's ``tf2_ros.Buffer`` shape.

A :class:`Buffer` stores, per child frame, a sliding window of stamped
transforms to its parent (dynamic, from ``/tf``) or one transform valid at all
times (static, from ``/tf_static``), and answers "what is ``T_target_source``
at time t" by walking both frames up to their common ancestor.

Semantics follow tf2 (``geometry2/tf2/src/buffer_core.cpp``, ``cache.cpp``):

* time 0 means "the latest time at which the whole chain is known": the
  minimum over the chain's links of their newest stamp, static links ignored
  (tf2's ``getLatestCommonTime``); an all-static chain resolves to time 0;
* between two stamps the translation is interpolated linearly and the
  rotation by slerp; an exact stamp is returned unchanged; before the oldest
  or after the newest sample of a link the lookup raises
  :class:`~visnav.tf.errors.ExtrapolationException` (no extrapolation);
* each frame keeps samples back to ``newest - cache_time``; inserting a sample
  older than that is refused (tf2's ``TF_OLD_DATA``);
* every sample records its own parent, so a frame can be re-parented; between
  two samples with different parents the older sample is used unchanged;
* a static transform replaces a dynamic cache of the same child (and vice versa);
* frame ids may not be empty or start with ``/`` in lookups
  (:class:`~visnav.tf.errors.InvalidArgumentException`); on insertion a leading
  ``/`` is stripped, as tf2 does;
* inserted transforms with NaN, a self-transform, an empty frame id, or a
  quaternion whose squared norm differs from 1 by 0.01 or more are refused
  (``set_transform`` logs why and returns False, tf2's ``TF_NAN_INPUT`` and
  ``TF_DENORMALIZED_QUATERNION``); an accepted quaternion is normalised
  (tf2 stores it as given).

Times are ``int`` nanoseconds, or ``builtin_interfaces/Time`` messages (and
objects with an integer ``nanoseconds`` attribute, like ``rclpy.time.Time``)
for code written against rclpy. Timeouts are wall-clock seconds (float) or a
``builtin_interfaces/Duration``, as rclpy waits on the system clock.

One lock guards all caches, so a listener thread may insert while other
threads look up.
"""

from __future__ import annotations

import difflib
import logging
import math
import threading
from math import isfinite
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.msgs.errors import MessageError
from visnav.msgs.time import duration_to_ns, time_to_ns
from visnav.msgs.types import (
    Duration,
    TransformStamped,
)
from visnav.tf import _scalar
from visnav.tf._buffer_io import (
    FrameInfo,
    TimeLike,
    frames_yaml,
    inverse_to_msg,
    pose_to_msg,
    timeout_s,
    to_ns,
)
from visnav.tf._cache import FrameCache
from visnav.tf._can_transform import CanTransformMixin
from visnav.tf._plan import (
    DOWNWARD,
    UPWARD,
    Plan,
    SideFn,
    build_plan,
    latest_time,
    make_side,
    run_plan,
    side,
)
from visnav.tf._scalar import IDENTITY, Pose7
from visnav.tf._tree import fmt_time, latest_common_time, walk
from visnav.tf.errors import (
    InvalidArgumentException,
    LookupException,
)
from visnav.tf.geometry import transform_full_object, transform_object

__all__ = ["Buffer", "FrameInfo", "TimeLike"]

_LOG = logging.getLogger("visnav.tf")

_NS_PER_S = 1_000_000_000
# tf2 refuses a quaternion when |x^2 + y^2 + z^2 + w^2 - 1| >= this.
_QUATERNION_NORMALIZATION_TOLERANCE = 10e-3


class Buffer(CanTransformMixin):
    """Stores stamped transforms and looks up ``T_target_source`` at any stored time.

    Args:
        cache_time: how much history to keep per frame, in seconds (or a
            ``builtin_interfaces/Duration``); tf2's default is 10 s.
        jit: compile the interpolation and composition arithmetic with numba: lookups
            about 15 % faster than the default (which is already below tf2's C++ core
            through its Python binding on the benchmark chain, see BENCHMARKS.md) for a
            one-time cost of about 0.5 s of CPU (numba's import and its on-disk cache;
            about a second more the first time on a machine), paid when the buffer is
            created. Results are equal to within 1e-12.

    Example:
        >>> from visnav.msgs import Header, Quaternion, Time, Transform, TransformStamped, Vector3
        >>> buf = Buffer()
        >>> msg = TransformStamped(
        ...     Header(Time(0, 0), "base_link"),
        ...     "camera",
        ...     Transform(Vector3(0.1, 0.0, 0.5), Quaternion(0.0, 0.0, 0.0, 1.0)),
        ... )
        >>> buf.set_transform_static(msg, "my_node")
        True
        >>> buf.lookup_transform_matrix("base_link", "camera")[:3, 3].tolist()
        [0.1, 0.0, 0.5]
    """

    def __init__(self, cache_time: float | Duration = 10.0, *, jit: bool = False) -> None:
        if isinstance(cache_time, Duration):
            cache_ns = duration_to_ns(cache_time)
        elif isinstance(cache_time, int | float) and not isinstance(cache_time, bool):
            if not math.isfinite(cache_time):
                msg = f"cache_time is {cache_time}: expected finite seconds >= 0"
                raise InvalidArgumentException(msg)
            cache_ns = round(float(cache_time) * _NS_PER_S)
        else:
            msg = f"cache_time is {cache_time!r}: expected seconds or a builtin_interfaces/Duration"
            raise InvalidArgumentException(msg)
        if cache_ns < 0:
            msg = f"cache_time is {cache_ns / _NS_PER_S} s: expected >= 0"
            raise InvalidArgumentException(msg)
        self._cache_time_ns = cache_ns
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        # Every frame id ever seen (child or parent), in first-seen order (tf2's frame numbers).
        self._known: dict[str, None] = {}
        # Child frame -> its cache. Root frames (only ever parents) have none.
        self._caches: dict[str, FrameCache] = {}
        # (target, source) -> precomputed chain; dropped whenever a cache is created or
        # replaced or a static transform changes (see visnav.tf._plan).
        self._plans: dict[tuple[str, str], Plan] = {}
        self._side: SideFn = make_side(*_scalar.jit_kernels()) if jit else side

    @property
    def cache_time_ns(self) -> int:
        """How far behind each frame's newest stamp samples are kept, in nanoseconds."""
        return self._cache_time_ns

    # ------------------------------------------------------------------ insertion

    def set_transform(
        self, transform: TransformStamped, authority: str, *, strict: bool = False
    ) -> bool:
        """Insert a dynamic transform (as received on ``/tf``).

        Args:
            transform: ``T_parent_child`` with ``header.frame_id`` = parent,
                ``child_frame_id`` = child and ``header.stamp`` its time.
            authority: who sent it (a node name); shown as the broadcaster in
                :meth:`all_frames_as_yaml`.
            strict: raise instead of logging and returning False.

        Returns:
            True if stored; False if refused (reason logged on the ``visnav.tf`` logger).

        Raises:
            InvalidArgumentException: only with ``strict=True``, for a refused transform.
        """
        return self._insert(transform, authority, is_static=False, strict=strict)

    def set_transform_static(
        self, transform: TransformStamped, authority: str, *, strict: bool = False
    ) -> bool:
        """Insert a static transform (as received on ``/tf_static``): valid at every time.

        A later static transform for the same child replaces it. Arguments and
        return value as :meth:`set_transform`.
        """
        return self._insert(transform, authority, is_static=True, strict=strict)

    def _refuse(self, code: str, text: str, *, strict: bool) -> bool:
        message = f"{code}: {text}"
        if strict:
            raise InvalidArgumentException(message)
        _LOG.error("%s", message)
        return False

    def _insert(
        self, transform: TransformStamped, authority: str, *, is_static: bool, strict: bool
    ) -> bool:
        parent = transform.header.frame_id.removeprefix("/")
        child = transform.child_frame_id.removeprefix("/")
        t, r = transform.transform.translation, transform.transform.rotation
        values = (float(t.x), float(t.y), float(t.z), float(r.x), float(r.y), float(r.z))
        qw = float(r.w)
        if not child:
            return self._refuse(
                "TF_NO_CHILD_FRAME_ID",
                f'transform from authority "{authority}" (parent "{parent}") has an empty '
                "child_frame_id: set the frame this transform places",
                strict=strict,
            )
        if not parent:
            return self._refuse(
                "TF_NO_FRAME_ID",
                f'transform for child "{child}" from authority "{authority}" has an empty '
                "header.frame_id: set the parent frame",
                strict=strict,
            )
        if child == parent:
            return self._refuse(
                "TF_SELF_TRANSFORM",
                f'transform from authority "{authority}" has frame_id and child_frame_id both '
                f'"{child}": a frame cannot be its own parent',
                strict=strict,
            )
        # one check for the common case: a NaN or an infinity makes the sum non-finite
        # (a sum that overflows with finite values is checked value by value)
        if not isfinite(sum(values) + qw) and not all(isfinite(v) for v in (*values, qw)):
            return self._refuse(
                "TF_NAN_INPUT",
                f'transform for child "{child}" from authority "{authority}" has a non-finite '
                f"value: translation ({values[0]}, {values[1]}, {values[2]}) rotation "
                f"({values[3]}, {values[4]}, {values[5]}, {qw})",
                strict=strict,
            )
        qx, qy, qz = values[3], values[4], values[5]
        norm2 = qx * qx + qy * qy + qz * qz + qw * qw
        if abs(norm2 - 1.0) >= _QUATERNION_NORMALIZATION_TOLERANCE:
            return self._refuse(
                "TF_DENORMALIZED_QUATERNION",
                f'transform for child "{child}" from authority "{authority}" has rotation '
                f"(x, y, z, w) = ({qx}, {qy}, {qz}, {qw}) with squared norm {norm2:.6g}: "
                f"expected a unit quaternion (within {_QUATERNION_NORMALIZATION_TOLERANCE})",
                strict=strict,
            )
        try:
            stamp = time_to_ns(transform.header.stamp)
        except MessageError as exc:
            return self._refuse(
                "TF_INVALID_STAMP", f'transform for child "{child}": {exc}', strict=strict
            )
        if stamp < 0:
            return self._refuse(
                "TF_INVALID_STAMP",
                f'transform for child "{child}" has a negative stamp {fmt_time(stamp)} s',
                strict=strict,
            )
        inv = 1.0 / math.sqrt(norm2)
        pose: Pose7 = (values[0], values[1], values[2], qx * inv, qy * inv, qz * inv, qw * inv)
        with self._lock:
            cache = self._caches.get(child)
            if cache is None or cache.is_static != is_static:
                cache = FrameCache(is_static=is_static, cache_time_ns=self._cache_time_ns)
                self._caches[child] = cache
                self._plans.clear()
            elif is_static:
                self._plans.clear()
            if not cache.insert(stamp, parent, pose):
                latest = cache.newest_ns
                oldest_allowed = latest - self._cache_time_ns
                _LOG.warning(
                    "TF_OLD_DATA: ignoring data from the past for frame %s at time %s s "
                    "according to authority %s: it is older than the cache window "
                    "(newest %s s - cache_time %s s = %s s)",
                    child,
                    fmt_time(stamp),
                    authority,
                    fmt_time(latest),
                    fmt_time(self._cache_time_ns),
                    fmt_time(oldest_allowed),
                )
                return False
            cache.authority = authority
            known = self._known
            if child not in known:
                known[child] = None
            if parent not in known:
                known[parent] = None
            if self._waiters:
                self._cond.notify_all()
        return True

    def clear(self) -> None:
        """Drop every dynamic sample; static transforms and known frame ids stay (as tf2).

        tf2_ros listeners call this when ROS time jumps back (a bag loop, a simulator
        reset); tf2's static caches ignore ``clear``, so the latched ``/tf_static``
        transforms, which are not sent again, survive it.
        """
        with self._lock:
            self._caches = {f: c for f, c in self._caches.items() if c.is_static}
            self._plans.clear()

    # ------------------------------------------------------------------ lookups

    def lookup_transform(
        self,
        target_frame: str,
        source_frame: str,
        time_ns: TimeLike = 0,
        *,
        timeout: float | Duration = 0.0,
    ) -> TransformStamped:
        """Return ``T_target_source``: the transform mapping points in source into target.

        Args:
            target_frame: the frame to transform into (``header.frame_id`` of the result).
            source_frame: the frame to transform from (``child_frame_id`` of the result).
            time_ns: the time, int nanoseconds or a ``builtin_interfaces/Time``; 0 means the
                latest time at which the whole chain is available.
            timeout: wait up to this many wall-clock seconds for the transform to become
                available (0: do not wait).

        Returns:
            The transform, stamped at the requested (or resolved latest common) time.

        Raises:
            LookupException: a frame is unknown (the message lists the closest known frames).
            ConnectivityException: the frames are in unconnected trees.
            ExtrapolationException: a link has no data at that time.
            InvalidArgumentException: an empty frame id, a leading ``/``, a bad time.
        """
        t = time_ns if type(time_ns) is int and time_ns >= 0 else to_ns(time_ns, "time")
        if timeout:
            self._wait(target_frame, source_frame, t, timeout_s(timeout))
        # acquire/release rather than ``with``: a third of the lock's cost on this hot path.
        lock = self._lock
        lock.acquire()
        try:
            plan = self._plans.get((target_frame, source_frame))
            pose = None
            inverted = False
            if plan is not None:
                resolved = t or latest_time(plan, self._caches)
                if resolved is not None:
                    kind = plan.kind
                    if kind == UPWARD:  # target is an ancestor of source
                        pose = self._side(plan.source_steps, resolved)
                    elif kind == DOWNWARD:  # source is the root above target: invert
                        pose = self._side(plan.target_steps, resolved)
                        inverted = True
                    else:
                        pose = run_plan(plan, resolved, self._caches, self._side)
            if pose is None:
                pose, resolved = self._lookup(target_frame, source_frame, t)
                inverted = False
        finally:
            lock.release()
        if inverted:
            return inverse_to_msg(pose, target_frame, source_frame, resolved)  # type: ignore[arg-type]
        return pose_to_msg(pose, target_frame, source_frame, resolved)  # type: ignore[arg-type]

    def lookup_transform_matrix(
        self,
        target_frame: str,
        source_frame: str,
        time_ns: TimeLike = 0,
        *,
        timeout: float | Duration = 0.0,
    ) -> NDArray[np.float64]:
        """Return ``T_target_source`` as a 4x4 float64 matrix (for numpy code).

        Arguments and errors as :meth:`lookup_transform`. Building the array costs about
        1 us more than :meth:`lookup_transform`'s message (bench/bench_tf.py).
        """
        t = to_ns(time_ns, "time")
        if timeout:
            self._wait(target_frame, source_frame, t, timeout_s(timeout))
        with self._lock:
            pose, _ = self._lookup(target_frame, source_frame, t)
        return np.array(_scalar.pose_to_rows(pose))

    def lookup_transform_full(
        self,
        target_frame: str,
        target_time: TimeLike,
        source_frame: str,
        source_time: TimeLike,
        fixed_frame: str,
        *,
        timeout: float | Duration = 0.0,
    ) -> TransformStamped:
        """Return the transform from source at ``source_time`` to target at ``target_time``.

        The chain goes through ``fixed_frame``, assumed not to move between the two
        times: ``T_target(t_target)_source(t_source) = T_target_fixed(t_target) @
        T_fixed_source(t_source)``. The classic use: where is, in the robot's frame now,
        an object seen by the robot one second ago (``fixed_frame`` = ``"odom"`` or ``"map"``).

        Args:
            target_frame: the frame to transform into.
            target_time: the time of the target frame (0: latest common time of target/fixed).
            source_frame: the frame to transform from.
            source_time: the time of the source frame (0: latest common time of fixed/source).
            fixed_frame: a frame that does not move between the two times.
            timeout: wall-clock seconds to wait for both halves (0: do not wait).

        Returns:
            The transform, stamped at the (resolved) target time.

        Raises:
            LookupException, ConnectivityException, ExtrapolationException,
            InvalidArgumentException: as :meth:`lookup_transform`.
        """
        tt = to_ns(target_time, "target_time")
        ts = to_ns(source_time, "source_time")
        if timeout:
            self._wait_full(target_frame, tt, source_frame, ts, fixed_frame, timeout_s(timeout))
        with self._lock:
            pose, resolved = self._lookup_full(target_frame, tt, source_frame, ts, fixed_frame)
        return pose_to_msg(pose, target_frame, source_frame, resolved)

    def lookup_transform_full_matrix(
        self,
        target_frame: str,
        target_time: TimeLike,
        source_frame: str,
        source_time: TimeLike,
        fixed_frame: str,
        *,
        timeout: float | Duration = 0.0,
    ) -> NDArray[np.float64]:
        """Return :meth:`lookup_transform_full`'s transform as a 4x4 float64 matrix."""
        tt = to_ns(target_time, "target_time")
        ts = to_ns(source_time, "source_time")
        if timeout:
            self._wait_full(target_frame, tt, source_frame, ts, fixed_frame, timeout_s(timeout))
        with self._lock:
            pose, _ = self._lookup_full(target_frame, tt, source_frame, ts, fixed_frame)
        return np.array(_scalar.pose_to_rows(pose))

    def transform(
        self,
        obj: Any,
        target_frame: str,
        timeout: float | Duration = 0.0,
        new_type: type[Any] | None = None,
    ) -> Any:
        """Return a stamped message expressed in ``target_frame`` (tf2_ros's ``transform``).

        Looks up ``T_target_source`` at ``obj.header.stamp`` (source:
        ``obj.header.frame_id``) and applies it with :mod:`visnav.tf.geometry`'s
        ``do_transform_*`` (points and poses move, vectors and wrenches only rotate);
        the result carries the transform's header.

        Args:
            obj: a PointStamped, Vector3Stamped, PoseStamped, PoseWithCovarianceStamped,
                WrenchStamped or PointCloud2.
            target_frame: the frame to express it in.
            timeout: wall-clock seconds to wait for the transform.
            new_type: None, or ``numpy.ndarray`` to convert the result.

        Raises:
            TransformException: an unsupported type; lookup errors as
                :meth:`lookup_transform`.
        """
        return transform_object(self, obj, target_frame, timeout=timeout, new_type=new_type)

    def transform_full(
        self,
        obj: Any,
        target_frame: str,
        target_time: TimeLike,
        fixed_frame: str,
        timeout: float | Duration = 0.0,
        new_type: type[Any] | None = None,
    ) -> Any:
        """:meth:`transform` through ``fixed_frame``, to ``target_frame`` at ``target_time``."""
        return transform_full_object(
            self,
            obj,
            target_frame,
            target_time,
            fixed_frame,
            timeout=timeout,
            new_type=new_type,
        )

    # ------------------------------------------------------------------ introspection

    def get_frames(self) -> list[str]:
        """Every frame id seen, as child or parent, in first-seen order."""
        with self._lock:
            return list(self._known)

    def has_frame(self, frame_id: str) -> bool:
        """Whether ``frame_id`` has been seen as a child or a parent."""
        with self._lock:
            return frame_id in self._known

    def get_parent(self, frame_id: str, time_ns: TimeLike = 0) -> str | None:
        """The parent of ``frame_id`` at ``time_ns`` (0: newest); None for a root or no data."""
        t = to_ns(time_ns, "time")
        with self._lock:
            cache = self._caches.get(frame_id)
            sample = cache.get(t) if cache is not None else None
        return sample[0] if sample is not None else None

    def frame_infos(self) -> dict[str, FrameInfo]:
        """Per child frame: parent, authority, rate and time range (first-seen order)."""
        with self._lock:
            out: dict[str, FrameInfo] = {}
            for frame in self._known:
                cache = self._caches.get(frame)
                if cache is None:
                    continue
                out[frame] = FrameInfo(
                    frame_id=frame,
                    parent=cache.parent,
                    authority=cache.authority,
                    is_static=cache.is_static,
                    rate_hz=cache.rate_hz(),
                    most_recent_ns=cache.newest_ns,
                    oldest_ns=cache.oldest_ns,
                    num_samples=len(cache.samples),
                )
            return out

    def all_frames_as_yaml(self, current_time: TimeLike | None = None) -> str:
        """The frames as tf2's ``allFramesAsYAML`` prints them (also the ``tf2_frames`` service).

        One mapping per child frame with ``parent``, ``broadcaster``, ``rate``,
        ``most_recent_transform``, ``oldest_transform``, ``transform_delay`` (only
        when ``current_time`` is given) and ``buffer_length``; ``[]`` when empty.
        """
        now = None if current_time is None else to_ns(current_time, "current_time")
        return frames_yaml(self.frame_infos(), now)

    def all_frames_as_string(self) -> str:
        """One line per child frame: ``Frame X exists with parent Y.`` (tf2's format)."""
        return "".join(
            f"Frame {info.frame_id} exists with parent {info.parent}.\n"
            for info in self.frame_infos().values()
        )

    # ------------------------------------------------------------------ internals (lock held)

    def _validate(self, frame: str, what: str) -> None:
        if not frame:
            msg = f'Invalid argument "" passed to {what}: tf2 frame ids cannot be empty'
            raise InvalidArgumentException(msg)
        if frame[0] == "/":
            hint = frame.lstrip("/")
            known = " (a known frame)" if hint in self._known else ""
            msg = (
                f'Invalid argument "{frame}" passed to {what}: tf2 frame ids cannot start '
                f"with a '/'; use \"{hint}\"{known}"
            )
            raise InvalidArgumentException(msg)
        if frame not in self._known:
            raise self._unknown(frame, what)

    def _unknown(self, frame: str, what: str) -> LookupException:
        if not self._known:
            msg = (
                f'"{frame}" passed to {what} does not exist: the buffer holds no frames yet '
                "(is a transform listener receiving /tf and /tf_static?)"
            )
            return LookupException(msg, frame=frame)
        close = difflib.get_close_matches(frame, list(self._known), n=3, cutoff=0.6)
        lowered = {k.lower(): k for k in self._known}
        if frame.lower() in lowered and lowered[frame.lower()] not in close:
            close.insert(0, lowered[frame.lower()])
        hint = (
            "closest known frames: " + ", ".join(f'"{c}"' for c in close)
            if close
            else f"known frames: {', '.join(sorted(self._known)[:12])}"
            + (" ..." if len(self._known) > 12 else "")
        )
        msg = f'"{frame}" passed to {what} does not exist; {hint}'
        return LookupException(msg, frame=frame, suggestions=close)

    def _lookup(self, target: str, source: str, t: int) -> tuple[Pose7, int]:
        plan = self._plans.get((target, source))
        if plan is not None:
            resolved = t if t else latest_time(plan, self._caches)
            if resolved is not None:
                pose = run_plan(plan, resolved, self._caches, self._side)
                if pose is not None:
                    return pose, resolved
        found = self._lookup_walk(target, source, t)
        if target != source:
            new_plan = build_plan(self._caches, target, source)
            if new_plan is not None:
                self._plans[target, source] = new_plan
        return found

    def _lookup_walk(self, target: str, source: str, t: int) -> tuple[Pose7, int]:
        if target == source:
            self._validate_format(target, "lookup_transform argument target_frame")
            if t == 0:
                cache = self._caches.get(target)
                t = cache.newest_ns if cache is not None else 0
            return IDENTITY, t
        self._validate(target, "lookup_transform argument target_frame")
        self._validate(source, "lookup_transform argument source_frame")
        if t == 0:
            t = latest_common_time(self._caches, target, source)
        return walk(self._caches, target, source, t, self._cache_time_ns), t

    def _validate_format(self, frame: str, what: str) -> None:
        if not frame or frame[0] == "/":
            self._validate(frame, what)

    def _lookup_full(
        self, target: str, tt: int, source: str, ts: int, fixed: str
    ) -> tuple[Pose7, int]:
        self._validate(target, "lookup_transform argument target_frame")
        self._validate(source, "lookup_transform argument source_frame")
        self._validate(fixed, "lookup_transform argument fixed_frame")
        fixed_source, _ = self._lookup(fixed, source, ts)
        target_fixed, resolved = self._lookup(target, fixed, tt)
        return _scalar.compose(target_fixed, fixed_source), resolved
