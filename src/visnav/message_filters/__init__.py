"""Message filters: chain topic inputs, cache them and synchronize them by stamp.

The ROS ``message_filters`` package with snake_case names::

    from visnav import message_filters

    left = message_filters.Subscriber(node, Image, "left/image_rect")
    right = message_filters.Subscriber(node, Image, "right/image_rect")
    sync = message_filters.ApproximateTime([left, right], queue_size=10)
    sync.register_callback(on_stereo_pair)

* :class:`SimpleFilter`: ``register_callback(cb, *args)`` / ``signal_message(*msgs)``.
* :class:`Subscriber`: a topic subscription as a filter (``node.create_subscription``).
* :class:`Cache`: the latest ``cache_size`` messages, queried by stamp.
* :class:`TimeSynchronizer`: one message per input with identical stamps.
* :class:`ApproximateTimeSynchronizer`: ROS 1 Python's slop-based synchronizer.
* :class:`ApproximateTime`: roscpp's ApproximateTime policy.

Stamps are ``header.stamp`` read as integer nanoseconds; durations given to the
constructors (``slop``, ``max_interval_duration``, ``inter_message_lower_bounds``)
are float seconds, as in ROS.

ApproximateTimeSynchronizer and ApproximateTime differ
-----------------------------------------------------
Both pair messages whose stamps are close; they are different algorithms and
give different sets on the same input.

* Tolerance. ``ApproximateTimeSynchronizer`` needs ``slop``: a set is emitted only
  when it spans strictly less than ``slop``. ``ApproximateTime`` has no tolerance:
  it emits the best set it can find, however wide (bound it with
  ``max_interval_duration``).
* Which set. ``ApproximateTimeSynchronizer`` acts on each arriving message: it
  builds a set around that message from the queued messages nearest to it and
  emits the first combination within ``slop``, even when waiting would have given
  a tighter set. ``ApproximateTime`` chooses, among the sets contiguous to the
  previous output, the one of smallest span (with ``age_penalty``).
* Order. ``ApproximateTimeSynchronizer`` can emit sets that cross or go back in
  time (an older queued message can still be matched after a newer set was
  emitted), and its output depends on the arrival interleaving. ``ApproximateTime``
  emits sets that never cross (each input's stamps increase from set to set) and
  its output depends only on the stamps.
* Latency. ``ApproximateTimeSynchronizer`` emits as soon as a set within ``slop``
  exists. ``ApproximateTime`` waits until no future message can give a better set,
  usually one message period per input (less with ``inter_message_lower_bounds``
  or a larger ``age_penalty``).
* Disorder. ``ApproximateTimeSynchronizer`` keys its queues by stamp, so it accepts
  messages in any order per input (a repeated stamp replaces the queued message);
  it logs the first backwards stamp per input. ``ApproximateTime`` expects
  non-decreasing stamps per input; like roscpp it keeps a message whose stamp
  goes backwards (queued in arrival order, warned once per input), or with
  ``reset=True`` restarts that input's queue.
* Queue. ``queue_size`` counts distinct stamps per input for the former and
  waiting messages per input for the latter (roscpp recommends at least 2).

Use ``ApproximateTime`` for new code (it is what roscpp and rclcpp nodes use);
use ``ApproximateTimeSynchronizer`` to reproduce a ROS Python node's output exactly.
"""

from __future__ import annotations

from visnav.message_filters._common import FilterLike, LoggerLike
from visnav.message_filters.approximate_time import ApproximateTime
from visnav.message_filters.cache import Cache
from visnav.message_filters.errors import MessageFilterError
from visnav.message_filters.simple_filter import NodeLike, SimpleFilter, Subscriber
from visnav.message_filters.time_synchronizer import (
    ApproximateTimeSynchronizer,
    TimeSynchronizer,
)

__all__ = [
    "ApproximateTime",
    "ApproximateTimeSynchronizer",
    "Cache",
    "FilterLike",
    "LoggerLike",
    "MessageFilterError",
    "NodeLike",
    "SimpleFilter",
    "Subscriber",
    "TimeSynchronizer",
]
