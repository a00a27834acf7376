"""visnav plot: rqt_plot's field names resolved against the graph, values as Rerun scalars."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rerun")

from visnav.msgs import LaserScan, Odometry, make
from visnav.viz import VizError
from visnav.viz.plot import PlotField, field_value, resolve_fields

TOPICS = ["/odom", "/odom/extra", "/scan", "/imu/data"]


def test_resolve_picks_the_longest_topic_prefix_and_splits_fields() -> None:
    (f,) = resolve_fields("/odom/twist/twist/linear/x", TOPICS)
    assert f == PlotField("/odom", ("twist", "twist", "linear", "x"))
    assert f.name == "/odom/twist/twist/linear/x"
    assert f.entity == "plot/odom/twist/twist/linear/x"
    (f,) = resolve_fields("/odom/extra/data", TOPICS)
    assert f.topic == "/odom/extra"
    xyz = resolve_fields("imu/data/linear_acceleration/x:y:z", TOPICS)
    assert [f.path[-1] for f in xyz] == ["x", "y", "z"]
    assert {f.topic for f in xyz} == {"/imu/data"}
    (f,) = resolve_fields("/scan/ranges[3]", TOPICS)
    assert f.path == ("ranges", "[3]")
    assert f.name == "/scan/ranges[3]"


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("/nothing/x", "no topic of the graph is a prefix.*/odom"),
        ("/odom", "no topic of the graph"),
        ("/odom/pose/1bad", "is not a field name"),
    ],
)
def test_resolve_errors_name_the_problem(spec: str, match: str) -> None:
    with pytest.raises(VizError, match=match):
        resolve_fields(spec, TOPICS)


def test_field_values_numbers_arrays_and_errors() -> None:
    odom = make(Odometry)
    odom.twist.twist.linear.x = 1.5
    assert field_value(odom, ("twist", "twist", "linear", "x")) == [1.5]
    scan = make(LaserScan, ranges=np.array([1.0, 2.0, 3.0], np.float32))
    assert field_value(scan, ("ranges", "[1]")) == [2.0]
    assert field_value(scan, ("ranges",)) == [1.0, 2.0, 3.0]
    with pytest.raises(VizError, match=r"no field .nope.*twist"):
        field_value(odom, ("nope",))
    with pytest.raises(VizError, match="index 9 is out of range"):
        field_value(scan, ("ranges", "[9]"))
    with pytest.raises(VizError, match="not a number"):
        field_value(odom, ("twist",))


def test_plot_feed_logs_scalars_of_live_messages(tmp_path: Path, vz: Any) -> None:
    from visnav.graph import Context, Node
    from visnav.viz import open_viewer
    from visnav.viz.plot import PlotFeed

    out = tmp_path / "plot.rrd"
    with Context(transport="local") as ctx, open_viewer(save=out) as viewer:
        pub_node = Node("talker", context=ctx)
        pub = pub_node.create_publisher(Odometry, "/odom", 10)
        listener = Node("_plotter", context=ctx)
        feed = PlotFeed(viewer.recording, listener, ["/odom/twist/twist/linear/x:y"])
        feed.resolve(wait_s=2.0)
        for i in range(5):
            msg = make(Odometry, header=vz.header("odom", (i + 1) * 10**9))
            msg.twist.twist.linear.x = float(i)
            msg.twist.twist.linear.y = -float(i)
            pub.publish(msg)
            ctx.spin_until(lambda i=i: feed.counts.get("/odom/twist/twist/linear/x", 0) > i, 2.0)
        feed.close()
    assert feed.counts == {"/odom/twist/twist/linear/x": 5, "/odom/twist/twist/linear/y": 5}
    rrd = vz.Rrd(out)
    xs = rrd.rows("plot/odom/twist/twist/linear/x", "Scalars:scalars")
    assert [v[0] for v in xs] == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert rrd.times("plot/odom/twist/twist/linear/x", "Scalars:scalars")[0] == 10**9
    assert [v[0] for v in rrd.rows("plot/odom/twist/twist/linear/y", "Scalars:scalars")][-1] == -4.0
