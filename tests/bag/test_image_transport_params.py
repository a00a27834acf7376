"""image_transport's plugin parameters for recorded images: names, values, the rvl format."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.bag import BagReader, BagRecorder
from visnav.bag.image_compression import (
    IMAGE_TRANSPORT_PARAMS,
    ImageCompression,
    decode_image,
    image_transport_from_args,
)
from visnav.cli.main import main
from visnav.errors import VisnavError
from visnav.graph import Context, Node
from visnav.msgs import Header, Image
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.time import ns_to_time
from visnav.perception.transport_codecs import ImageTransportError


def _noisy_depth(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:60, 0:80]
    depth = (1.0 + 0.05 * x + 0.02 * y + rng.normal(0.0, 0.01, (60, 80))).astype(np.float32)
    depth[3, 4] = np.nan
    depth[5, 6] = 11.0  # beyond depth_max
    return depth


def _colour() -> np.ndarray:
    y, x = np.mgrid[0:60, 0:80]
    return np.stack([x * 3, y * 4, (x * y) % 256], axis=-1).astype(np.uint8)


def test_defaults_are_ros1_image_transport_plugins() -> None:
    policy = ImageCompression()
    assert (policy.jpeg_quality, policy.png_level) == (80, 9)
    assert (policy.depth_format, policy.depth_png_level) == ("png", 1)
    assert (policy.depth_max, policy.depth_quantization) == (10.0, 100.0)
    assert image_transport_from_args(None) == policy


def test_params_by_plugin_names_ros2_and_ros1_spelling() -> None:
    policy = image_transport_from_args(
        [
            "compressed.jpeg_quality=50",
            "/compressedDepth/format:=rvl",
            "compressedDepth.depth_max=6",
        ]
    )
    assert (policy.jpeg_quality, policy.depth_format, policy.depth_max) == (50, "rvl", 6.0)
    assert set(IMAGE_TRANSPORT_PARAMS) >= {"compressed.jpeg_quality", "compressedDepth.format"}
    assert ImageCompression.from_params({"compressedDepth.png_level": 3}).depth_png_level == 3


@pytest.mark.parametrize(
    ("items", "match"),
    [
        (["jpeg_quality=50"], "'jpeg_quality' is not known: expected one of compressed.jpeg"),
        (["compressed.jpeg_quality"], "expected NAME=VALUE"),
        (["compressed.jpeg_quality=high"], "jpeg_quality is 'high': expected a int"),
        (["compressed.jpeg_quality=0"], r"jpeg_quality is 0: expected an int in \[1, 100\]"),
        (["compressedDepth.format=jpeg"], "compressedDepth.format is 'jpeg': expected 'png'"),
        (["compressedDepth.depth_max=-1"], "depth_max"),
    ],
)
def test_bad_params_name_the_parameter(items: list[str], match: str) -> None:
    with pytest.raises(ImageTransportError, match=match):
        image_transport_from_args(items)


def test_rvl_decodes_to_the_same_depth_as_png() -> None:
    image = numpy_to_image(_noisy_depth(), "32FC1")
    png = ImageCompression().encode(image, "compressedDepth")
    rvl = ImageCompression(depth_format="rvl").encode(image, "compressedDepth")
    assert rvl.format == "32FC1; compressedDepth rvl"
    assert bytes(rvl.data[:12]) == bytes(png.data[:12])  # one ConfigHeader (A, B)
    a, b = image_to_numpy(decode_image(png)), image_to_numpy(decode_image(rvl))
    assert np.array_equal(np.isnan(a), np.isnan(b))
    assert np.isnan(b[3, 4])
    assert np.isnan(b[5, 6])
    assert np.array_equal(a[~np.isnan(a)], b[~np.isnan(b)])
    millimetres = numpy_to_image(np.nan_to_num(_noisy_depth() * 1000).astype(np.uint16), "16UC1")
    rvl_mm = ImageCompression(depth_format="rvl").encode(millimetres, "compressedDepth")
    want = image_to_numpy(millimetres).copy()
    want[want > 10000] = 0
    assert np.array_equal(image_to_numpy(decode_image(rvl_mm)), want)


def test_jpeg_quality_trades_size_for_error() -> None:
    image = numpy_to_image(_colour(), "rgb8")
    sizes, errors = [], []
    for quality in (95, 80, 50):
        msg = ImageCompression(jpeg_quality=quality).encode(image, "compressed")
        back = image_to_numpy(decode_image(msg)).astype(int)
        sizes.append(len(msg.data))
        errors.append(np.abs(back - _colour().astype(int)).mean())
    assert sizes[0] > sizes[1] > sizes[2]
    assert errors[0] < errors[2]


def test_bag_record_cli_rejects_a_bad_parameter(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["bag", "record", "-a", "--image-transport", "compressed.quality=5"])
    assert code != 0
    err = capsys.readouterr().err
    assert "compressed.quality" in err
    assert "compressed.jpeg_quality" in err


@settings(max_examples=100, deadline=None)
@given(
    st.lists(
        st.text(max_size=40)
        | st.builds(
            lambda n, v: f"{n}={v}",
            st.sampled_from(sorted(IMAGE_TRANSPORT_PARAMS)),
            st.text(max_size=12) | st.sampled_from(["nan", "inf", "-0", "1e400", "9", "rvl"]),
        ),
        max_size=4,
    )
)
def test_fuzz_image_transport_args_raise_only_visnav_errors(items: list[str]) -> None:
    try:
        policy = image_transport_from_args(items)
    except VisnavError:
        return
    assert isinstance(policy, ImageCompression)


def test_run_image_transport_flag_reaches_the_runner(monkeypatch: pytest.MonkeyPatch) -> None:
    import argparse

    from visnav.cli import run as run_cli

    parser = argparse.ArgumentParser()
    run_cli.add_arguments(parser)
    seen: dict[str, object] = {}

    def fake_run(name: str, **kwargs: object) -> dict[str, object]:
        seen.update(kwargs)
        return {}

    monkeypatch.setattr(run_cli, "run_scenario", fake_run)
    argv = [
        "--image-transport",
        "compressedDepth.format=rvl",
        "--image-transport",
        "compressed.jpeg_quality=50",
        "car",
    ]
    run_cli._run(parser.parse_args(argv), interrupt=None)  # type: ignore[arg-type]
    assert seen["record_images"] is True  # implied
    assert seen["image_transport"] == ImageCompression(jpeg_quality=50, depth_format="rvl")
    seen.clear()
    run_cli._run(parser.parse_args(["car", "--record-images"]), interrupt=None)  # type: ignore[arg-type]
    assert seen["image_transport"] == ImageCompression()
    both = ["car", "--raw-images", "--image-transport", "compressed.jpeg_quality=50"]
    with pytest.raises(ImageTransportError, match="give one of the two"):
        run_cli._run(parser.parse_args(both), interrupt=None)  # type: ignore[arg-type]


def test_recorded_rvl_and_jpeg50_bag_reads_in_doctor(tmp_path: Path, local_ctx: Context) -> None:
    from visnav.doctor.bag_source import observe_bag

    node = Node("camera", context=local_ctx)
    colour = node.create_publisher(Image, "/camera/image_raw", 10)
    depth = node.create_publisher(Image, "/depth_camera/depth/image_raw", 10)
    policy = image_transport_from_args(["compressedDepth.format=rvl", "compressed.jpeg_quality=50"])
    rec = BagRecorder(local_ctx, None, tmp_path / "bag", image_transport=policy)
    rec.start()
    local_ctx.spin_some()
    for i in range(3):
        header = Header(stamp=ns_to_time(1_000_000_000 * (i + 1)), frame_id="cam")
        colour.publish(numpy_to_image(_colour(), "rgb8", header=header))
        depth.publish(numpy_to_image(_noisy_depth(), "32FC1", header=header))
        local_ctx.spin_some()
        rec.poll()
    path = rec.stop()
    with BagReader(path) as reader:
        formats = {m.topic: m.msg.format for m in reader.messages()}
    assert formats == {
        "/camera/image_raw/compressed": "rgb8; jpeg compressed bgr8",
        "/depth_camera/depth/image_raw/compressedDepth": "32FC1; compressedDepth rvl",
    }
    obs = observe_bag(path)
    got = obs.topics["/depth_camera/depth/image_raw"].samples[-1].msg
    assert got.encoding == "32FC1"
    back = image_to_numpy(got)
    want = _noisy_depth()
    ok = np.isfinite(want) & (want < 10.0)
    assert np.all(np.isfinite(back[ok]))
    assert np.abs(back[ok] - want[ok]).max() < (want[ok] ** 2 / 10100).max() * 1.01
