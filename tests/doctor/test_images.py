"""Image faults: layout, encoding, RGB/BGR swap, black/blank/saturated, depth validity and units."""

from __future__ import annotations

from typing import Any

import numpy as np

from visnav.msgs import image_to_numpy, numpy_to_image

IMG = "/camera/image_raw"
DEPTH = "/depth_camera/depth/image_raw"


def _pixels(fn: Any) -> Any:
    """A mutation replacing an image's pixels by ``fn(array)`` (same encoding)."""

    def apply(m: Any, i: int) -> Any:
        return numpy_to_image(fn(image_to_numpy(m).copy()), m.encoding, header=m.header)

    return apply


def test_step_too_small(dr: Any, clean_events: Any) -> None:
    def bad(m: Any, i: int) -> Any:
        m.step = m.width * 2
        return m

    report = dr.run(dr.mutate(clean_events, IMG, bad))
    f = dr.one(report, "images.size_mismatch", subject=IMG, encoding="rgb8", step=128)
    assert f.evidence["bytes_per_pixel"] == 3
    assert "step 128 < width * bytes_per_pixel = 192" in f.evidence["problem"]


def test_encoding_that_does_not_fit_the_data(dr: Any, clean_events: Any) -> None:
    # bgra8 label on rgb8 bytes: step says 4 bytes per pixel, data hold 3
    def bad(m: Any, i: int) -> Any:
        m.encoding = "rgba8"
        m.step = m.width * 4
        return m

    report = dr.run(dr.mutate(clean_events, IMG, bad))
    f = dr.one(report, "images.size_mismatch", subject=IMG, encoding="rgba8")
    assert f.evidence["data_bytes"] == 64 * 48 * 3
    assert f.evidence["step_the_data_implies"] == 192
    assert f.evidence["bytes_per_pixel_the_data_implies"] == 3


def test_unknown_encoding(dr: Any, clean_events: Any) -> None:
    def bad(m: Any, i: int) -> Any:
        m.encoding = "RGB8"
        return m

    report = dr.run(dr.mutate(clean_events, IMG, bad))
    f = dr.one(report, "images.size_mismatch", subject=IMG, encoding="RGB8")
    assert "not a known image encoding" in f.evidence["problem"]


def test_encoding_differs_from_declared(dr: Any, clean_events: Any) -> None:
    def relabel(m: Any, i: int) -> Any:
        m.encoding = "bgr8"
        return m

    report = dr.run(
        dr.mutate(clean_events, IMG, relabel), expect={"topics": {IMG: {"encoding": "rgb8"}}}
    )
    dr.one(report, "images.encoding_unexpected", encoding="bgr8", declared="rgb8")


def test_rgb_bgr_swap_from_the_sky(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, IMG, _pixels(lambda a: a[:, :, ::-1])))
    f = dr.one(report, "images.rgb_bgr_swap", subject=IMG, cue="sky", severity=dr.S.WARNING)
    r, g, b = f.evidence["top_band_rgb"]
    assert r > g > b  # the blue sky reads orange
    assert f.evidence["frames_voting_swapped"] == f.evidence["frames_sampled"]


def test_rgb_bgr_swap_from_the_ground(dr: Any) -> None:
    events = dr.stream(sky=False)  # grey top: no sky cue
    dr.none_of(dr.run(events), "images.rgb_bgr_swap")
    report = dr.run(dr.mutate(events, IMG, _pixels(lambda a: a[:, :, ::-1])))
    f = dr.one(report, "images.rgb_bgr_swap", subject=IMG, cue="ground")
    assert f.evidence["bottom_warmth"] < -0.2


def test_bgr8_label_with_rgb_data(dr: Any, clean_events: Any) -> None:
    def relabel(m: Any, i: int) -> Any:
        m.encoding = "bgr8"
        return m

    report = dr.run(dr.mutate(clean_events, IMG, relabel))
    dr.one(report, "images.rgb_bgr_swap", subject=IMG, encoding="bgr8", cue="sky")


def test_rgb_bgr_swap_from_a_known_colour(dr: Any) -> None:
    events = dr.stream(sky=False)
    expect = {"topics": {IMG: {"known_color": {"region": [0, 0.8, 1, 1], "rgb": [140, 105, 70]}}}}
    dr.none_of(dr.run(events, expect=expect), "images.rgb_bgr_swap")
    report = dr.run(dr.mutate(events, IMG, _pixels(lambda a: a[:, :, ::-1])), expect=expect)
    f = dr.one(report, "images.rgb_bgr_swap", cue="known colour")
    measured = f.evidence["known_color"]["measured"]
    assert measured[2] > measured[0]  # brown ground measured blue-ish


def test_black_frames(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, IMG, _pixels(lambda a: a * 0)))
    f = dr.one(report, "images.black", subject=IMG, severity=dr.S.ERROR)
    assert f.evidence["mean_level"] == 0.0


def test_some_black_frames_are_a_warning(dr: Any, clean_events: Any) -> None:
    blacken = _pixels(lambda a: a * 0)
    report = dr.run(dr.mutate(clean_events, IMG, lambda m, i: blacken(m, i) if i < 20 else m))
    f = dr.one(report, "images.black", subject=IMG, severity=dr.S.WARNING)
    assert 0 < f.evidence["frames_affected"] < f.evidence["frames_sampled"]


def test_saturated_frames(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, IMG, _pixels(lambda a: np.full_like(a, 255))))
    f = dr.one(report, "images.saturated", subject=IMG)
    assert f.evidence["saturated_fraction"] == 1.0


def test_blank_frames(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, IMG, _pixels(lambda a: np.full_like(a, 90))))
    f = dr.one(report, "images.blank", subject=IMG, severity=dr.S.ERROR)
    assert f.evidence["std_level"] == 0.0
    dr.none_of(report, "images.black", "images.saturated")


def test_depth_all_nan(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, DEPTH, _pixels(lambda a: a * np.nan)))
    f = dr.one(report, "images.depth_invalid", subject=DEPTH, severity=dr.S.ERROR)
    assert f.evidence["nan_fraction"] == 1.0


def test_depth_all_zero(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, DEPTH, _pixels(lambda a: a * 0)))
    f = dr.one(report, "images.depth_invalid", subject=DEPTH)
    assert f.evidence["zero_fraction"] == 1.0


def test_32fc1_in_millimetres(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, DEPTH, _pixels(lambda a: a * 1000.0)))
    f = dr.one(report, "images.depth_unit", subject=DEPTH, encoding="32FC1")
    assert "millimetres" in f.title
    assert 3000 < f.evidence["median_value"] < 4500


def test_16uc1_against_a_metre_consumer(dr: Any, clean_events: Any) -> None:
    def to_mm(m: Any, i: int) -> Any:
        mm = (image_to_numpy(m) * 1000).astype(np.uint16)
        return numpy_to_image(mm, "16UC1", header=m.header)

    events = dr.mutate(clean_events, DEPTH, to_mm)
    dr.none_of(dr.run(events), "images.depth_unit")  # valid 16UC1 millimetres
    report = dr.run(events, expect={"topics": {DEPTH: {"depth_unit": "m"}}})
    f = dr.one(report, "images.depth_unit", subject=DEPTH, encoding="16UC1")
    assert "1000x a 32FC1 consumer" in f.title
    assert f.evidence["consumer_expects"] == "32FC1 metres"


def test_16uc1_holding_metres(dr: Any, clean_events: Any) -> None:
    def to_m16(m: Any, i: int) -> Any:
        return numpy_to_image(image_to_numpy(m).astype(np.uint16), "16UC1", header=m.header)

    report = dr.run(dr.mutate(clean_events, DEPTH, to_m16))
    f = dr.one(report, "images.depth_unit", subject=DEPTH, encoding="16UC1")
    assert "look like metres" in f.title


def test_32fc1_against_a_millimetre_consumer(dr: Any, clean_events: Any) -> None:
    report = dr.run(clean_events, expect={"topics": {DEPTH: {"depth_unit": "mm"}}})
    f = dr.one(report, "images.depth_unit", subject=DEPTH)
    assert f.evidence["consumer_expects"] == "16UC1 millimetres"
