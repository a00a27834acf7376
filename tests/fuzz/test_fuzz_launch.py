"""Fuzz the launch loader: visnav YAML launch files and roslaunch XML files.

Mutated versions of valid files (and random text) are loaded with
:func:`visnav.launch.loader.load_launch`; only LaunchError (a VisnavError) may escape.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from visnav.launch.loader import load_launch
from visnav.launch.yaml_format import ENTRY_KEYS

from .conftest import FUZZ, FUZZ_STRUCTURED, mutated, only_visnav_errors

YAML_SEED = b"""\
launch:
  - arg: {name: robot, default: car, description: "car or quad"}
  - arg: {name: scan, default: "true", choices: ["true", "false"]}
  - let: {name: rate, value: "15"}
  - group:
      namespace: $(arg robot)
      use_sim_time: true
      remap: {a: b}
      children:
        - node:
            exec: depthimage_to_laserscan
            name: depth_to_scan
            if: $(arg scan)
            params: {range_max: 8.0, output_frame: camera_link, list: [1, 2]}
            remap: {depth: /front/depth/image_raw}
        - node: {exec: image_proc, namespace: cam, params: {queue_size: $(arg rate)}}
  - node:
      exec: static_transform_publisher
      args: ["0", "0", "0", "0", "0", "0", "map", "odom"]
"""

XML_SEED = b"""\
<?xml version="1.0"?>
<launch>
  <arg name="x" default="0"/>
  <arg name="rviz" default="false"/>
  <arg name="twice" value="$(eval arg('x') * 2 + 1)"/>
  <param name="rate" type="double" value="30.0"/>
  <param name="label" value="$(eval 'cam_' + str(twice) if x == 0 else 'none')"/>
  <rosparam>{a: 1, b: [1, 2]}</rosparam>
  <node pkg="tf2_ros" type="static_transform_publisher" name="tf1"
        args="0 0 $(arg x) 0 0 0 map odom"/>
  <group ns="camera">
    <node pkg="image_proc" type="image_proc" name="image_proc">
      <remap from="image" to="depth/image_raw"/>
      <param name="queue_size" value="5"/>
    </node>
  </group>
  <node if="$(arg rviz)" name="rviz" pkg="rviz" type="rviz"/>
</launch>
"""


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_launch")


def test_seeds_load(workdir: Path) -> None:
    for name, seed in (("seed.launch.yaml", YAML_SEED), ("seed.launch", XML_SEED)):
        path = workdir / name
        path.write_bytes(seed)
        assert load_launch(path).nodes, name


@FUZZ
@given(blob=mutated(YAML_SEED))
def test_mutated_yaml_launch(workdir: Path, blob: bytes) -> None:
    path = workdir / "fuzz.launch.yaml"
    path.write_bytes(blob)
    only_visnav_errors(load_launch, path, {"robot": "quad"})


@FUZZ
@given(blob=mutated(XML_SEED))
def test_mutated_roslaunch_xml(workdir: Path, blob: bytes) -> None:
    path = workdir / "fuzz.launch"
    path.write_bytes(blob)
    only_visnav_errors(load_launch, path, {"x": "1"})


@FUZZ
@given(text=st.text(max_size=200), suffix=st.sampled_from([".yaml", ".launch", ".xml"]))
def test_random_text_launch(workdir: Path, text: str, suffix: str) -> None:
    path = workdir / f"random{suffix}"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    only_visnav_errors(load_launch, path)


# --------------------------------------------------------------------------- structure-aware
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-3, 3),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(
        ["", "x", "true", "own", "shared", "/ns", "a/b", "$(arg a)", "$(env HOME)", "$(find x)",
         "image_proc", "static_transform_publisher", "my.mod:Cls", "$(dirname)/x.yaml", "a:=b"]
    ),
)  # fmt: skip
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=3), st.dictionaries(st.sampled_from(["a", "b", "x"]), inner)
    ),
    max_leaves=6,
)


@st.composite
def entries(draw: st.DrawFn, depth: int = 0) -> dict[str, object]:
    kind = draw(st.sampled_from(sorted(ENTRY_KEYS)))
    keys = draw(st.lists(st.sampled_from([*sorted(ENTRY_KEYS[kind]), "bogus"]), max_size=5))
    body: dict[str, object] = {}
    for key in keys:
        if key == "children" and depth < 2:
            body[key] = draw(st.lists(entries(depth + 1), max_size=3))
        else:
            body[key] = draw(values)
    return {kind: draw(st.one_of(st.just(body), values)) if depth < 3 else body}


@FUZZ_STRUCTURED
@given(launch=st.lists(entries(), max_size=5), top=st.sampled_from(["launch", "nodes"]))
def test_structured_yaml_launch(workdir: Path, launch: list[object], top: str) -> None:
    path = workdir / "structured.launch.yaml"
    path.write_text(yaml.safe_dump({top: launch}))
    only_visnav_errors(load_launch, path, {"a": "1"})
