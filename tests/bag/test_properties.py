"""Property tests: any messages written in any format read back the same; QoS YAML round trip."""

from __future__ import annotations

import tempfile
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.rosbag2.metadata import parse_qos

from visnav.bag import BagWriter, read_bag
from visnav.bag.qos import playback_qos, qos_from_profile, qos_to_yaml
from visnav.graph import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from visnav.msgs import String, serialize

events = st.lists(
    st.tuples(
        st.sampled_from(["/a", "/b/c", "/d"]),
        st.integers(min_value=0, max_value=2**32 * 10**9 - 1),
        st.text(max_size=40),
    ),
    max_size=25,
)


@settings(max_examples=30, deadline=None)
@given(
    events=events,
    fmt=st.sampled_from([("mcap", "none"), ("mcap", "lz4"), ("ros1", "bz2"), ("sqlite3", "none")]),
)
def test_written_messages_read_back(
    events: list[tuple[str, int, str]], fmt: tuple[str, str]
) -> None:
    with tempfile.TemporaryDirectory() as d:
        with BagWriter(Path(d) / "p", fmt=fmt[0], compression=fmt[1]) as w:
            handles = {t: w.add_topic(t, "std_msgs/msg/String") for t in ("/a", "/b/c", "/d")}
            for topic, t, text in events:
                w.write(handles[topic], t, serialize(String(data=text)))
        got = [(m.topic, m.t_ns, m.msg.data) for m in read_bag(w.path)]
    assert [g[1] for g in got] == sorted(g[1] for g in got)
    assert len(got) == len(events)
    for topic in ("/a", "/b/c", "/d"):
        want = sorted((t, text) for tp, t, text in events if tp == topic)
        assert sorted((t, text) for tp, t, text in got if tp == topic) == want


profiles = st.builds(
    QoSProfile,
    depth=st.integers(min_value=1, max_value=1000),
    history=st.sampled_from(list(HistoryPolicy)),
    reliability=st.sampled_from(list(ReliabilityPolicy)),
    durability=st.sampled_from(list(DurabilityPolicy)),
)


@settings(deadline=None)  # a pure function: the default 200 ms deadline fails on a loaded machine
@given(st.lists(profiles, max_size=4))
def test_qos_yaml_round_trip(ps: list[QoSProfile]) -> None:
    qos = [qos_from_profile(p) for p in ps]
    assert parse_qos(qos_to_yaml(qos)) == qos
    play = playback_qos(qos)
    if ps:
        best_effort = any(p.reliability is ReliabilityPolicy.BEST_EFFORT for p in ps)
        assert (play.reliability is ReliabilityPolicy.BEST_EFFORT) == best_effort
        latched = all(p.durability is DurabilityPolicy.TRANSIENT_LOCAL for p in ps)
        assert (play.durability is DurabilityPolicy.TRANSIENT_LOCAL) == latched
