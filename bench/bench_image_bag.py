"""Image bags: bytes per simulated second with raw vs compressed images, and encode cost.

Run: ``python bench/bench_image_bag.py`` (``--duration S`` simulated seconds per run, default
3; ``--ideal-sensors`` also measures the noise-free cameras; ``--repeats N`` encode repeats).
``--runs RAW_DIR COMPRESSED_DIR`` reads two finished runs instead (e.g. 30 s runs made with
``visnav run car --duration 30 --record-images [--raw-images] --out DIR``, which take ~17 min
each on a loaded 2-core machine) and prints the same figure with the bytes per frame of each
image topic; it also prints compressedDepth's quantisation error at 1, 3 and 5 m.
``--bag RAW_BAG [--start S] [--seconds N]`` re-records a window of a finished run's raw
bag (``--raw-images``) through the recorder's writer and encoder, once raw (the reference)
and once per set of image_transport parameters (ROS 1 defaults, ``compressedDepth.format``
``rvl``, ``compressed.jpeg_quality`` 50, both), with the same zstd chunks as a run's bag:
bag bytes per simulated second, ratio to raw, encode CPU per frame, the depth error
against the raw depth at 1, 3 and 5 m and the colour error (mean absolute, PSNR).

* Bag size: two short car runs in this process, ``visnav run car --record-images
  --raw-images`` (the reference: images as published, zstd MCAP chunks as every run's bag)
  and ``--record-images`` (``<topic>/compressed`` JPEG, ``<topic>/compressedDepth`` PNG),
  same seed, no SLAM. Figure: bag bytes per simulated second (the summary's
  ``bag_mb_per_sim_s``) and the ratio raw / compressed (goal >= 8). The first half second
  (start-up, before the cameras render) is part of both. ``--image-transport NAME=VALUE...``
  adds a third run with those image_transport parameters (as ``visnav run``'s flag).
* Encode cost: the recorder's job per frame (CDR Image -> CompressedImage CDR, on its
  writer thread) on the raw run's own frames, median of ``--repeats`` passes, per topic, as
  wall and CPU (process) time (CPU is what it costs on a loaded machine); the decode CPU time
  of the readers (view, doctor, slam, bag play --decompress); and the compressedDepth PNG at
  zlib levels 1 (the plugin's default) and 9 and the RVL format, for size/time (per message:
  the bag's zstd chunks shrink RVL further, not PNG; ``--bag`` measures that).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any


def _run(
    out: Path, *, raw: bool, duration: float, ideal: bool, transport: Any = None
) -> dict[str, Any]:
    from visnav.graph import Context
    from visnav.scenarios.runner import run_scenario

    with Context(transport="local") as ctx:
        return run_scenario(
            "car",
            seed=0,
            duration_s=duration,
            out=out,
            context=ctx,
            progress=None,
            slam=False,
            ideal_sensors=ideal,
            record_images=True,
            raw_images=raw,
            image_transport=transport,
        )


def _frames(bag: str) -> dict[str, list[bytes]]:
    from visnav.bag import BagReader

    out: dict[str, list[bytes]] = {}
    with BagReader(bag) as reader:
        images = [n for n, m in reader.topics.items() if m.type_name == "sensor_msgs/msg/Image"]
        for raw in reader.raw_messages(images):
            out.setdefault(raw.topic, []).append(bytes(raw.data))
    return out


def _encode_costs(frames: dict[str, list[bytes]], repeats: int) -> None:
    from visnav.bag.image_compression import (
        COMPRESSED_IMAGE,
        IMAGE,
        ImageCompression,
        decode_image,
    )
    from visnav.msgs.serde import deserialize

    policies = {
        "default": ImageCompression(),
        "png9": ImageCompression(depth_png_level=9),
        "rvl": ImageCompression(depth_format="rvl"),
    }
    print(
        f"{'topic':<30} {'coding':<21} {'raw KB':>7} {'out KB':>7} {'x':>6} "
        f"{'enc ms':>7} {'enc cpu':>7} {'dec cpu':>7}"
    )
    for topic, datas in sorted(frames.items()):
        encoding = str(deserialize(datas[0], IMAGE).encoding)
        transport = ImageCompression.transport_for(encoding)
        for label, policy in policies.items():
            if label != "default" and transport != "compressedDepth":
                continue
            sample = datas[-8:] if label != "default" else datas[-30:]
            passes = repeats if label == "default" else 1
            times: list[float] = []
            cpu: list[float] = []
            encoded: list[bytes] = []
            for _ in range(passes):
                t0, c0 = time.perf_counter(), time.process_time()
                encoded = [policy.encode_cdr(d, transport) for d in sample]
                times.append((time.perf_counter() - t0) / len(sample))
                cpu.append((time.process_time() - c0) / len(sample))
            sizes = [len(e) for e in encoded]
            c0 = time.process_time()
            for e in encoded:
                decode_image(deserialize(e, COMPRESSED_IMAGE))
            dec = (time.process_time() - c0) / len(encoded)
            raw_kb = statistics.median(len(d) for d in sample) / 1e3
            out_kb = statistics.median(sizes) / 1e3
            coding = f"{transport} {label}" if label != "default" else transport
            print(
                f"{topic:<30} {coding:<21} {raw_kb:7.0f} {out_kb:7.1f} {raw_kb / out_kb:6.1f} "
                f"{statistics.median(times) * 1e3:7.2f} {statistics.median(cpu) * 1e3:7.2f} "
                f"{dec * 1e3:7.2f}"
            )


def _per_topic(bag: str) -> dict[str, tuple[int, int]]:
    """``{image topic: (messages, CDR bytes)}`` of a bag's Image / CompressedImage topics."""
    from visnav.bag import BagReader

    out: dict[str, tuple[int, int]] = {}
    with BagReader(bag) as reader:
        kinds = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
        topics = [n for n, m in reader.topics.items() if m.type_name in kinds]
        for raw in reader.raw_messages(topics):
            n, size = out.get(raw.topic, (0, 0))
            out[raw.topic] = (n + 1, size + len(raw.data))
    return out


def _from_runs(raw_dir: Path, compressed_dir: Path) -> None:
    import json

    rows = {}
    for label, folder in (("raw images", raw_dir), ("compressed", compressed_dir)):
        s = json.loads((folder / "summary.json").read_text())
        rows[label] = s
        print(
            f"  {label:<11} bag {s['bag_bytes'] / 1e6:8.2f} MB over {s['sim_duration_s']:g} "
            f"simulated s: {s['bag_mb_per_sim_s']:7.3f} MB per simulated s  "
            f"(RTF {s['real_time_factor']})"
        )
        for topic, (n, size) in sorted(_per_topic(s["bag"]).items()):
            print(f"      {topic:<48} {n:5d} msgs {size / max(n, 1) / 1e3:8.1f} KB each")
    ratio = rows["raw images"]["bag_bytes"] / rows["compressed"]["bag_bytes"]
    verdict = "meets" if ratio >= 8.0 else "misses"
    print(f"  ratio raw / compressed: {ratio:.2f}x ({verdict} the goal >= 8x)")


def _quantisation_error() -> None:
    import numpy as np

    from visnav.bag.image_compression import ImageCompression, decode_image
    from visnav.msgs.image import image_to_numpy, numpy_to_image

    print("compressedDepth 32FC1 quantisation (defaults: depth_quantization 100, depth_max 10):")
    for metres in (1.0, 3.0, 5.0):
        depth = np.linspace(metres - 0.01, metres + 0.01, 4096, dtype=np.float32).reshape(64, 64)
        msg = ImageCompression().encode(numpy_to_image(depth, "32FC1"), "compressedDepth")
        err = image_to_numpy(decode_image(msg)).astype(np.float64) - depth
        print(
            f"  {metres:g} m: error {err.min() * 1e3:+.3f} .. {err.max() * 1e3:+.3f} mm, "
            f"mean {err.mean() * 1e3:+.3f} mm (step d^2/(A-d) = "
            f"{metres**2 / (10100 - metres) * 1e3:.3f} mm)"
        )


_POLICIES: dict[str, dict[str, str]] = {
    "ROS 1 defaults": {},
    "compressedDepth.format=rvl": {"compressedDepth.format": "rvl"},
    "compressed.jpeg_quality=50": {"compressed.jpeg_quality": "50"},
    "jpeg_quality=50 + format=rvl": {
        "compressed.jpeg_quality": "50",
        "compressedDepth.format": "rvl",
    },
}


def _errors(raw: Any, decoded: Any, stats: dict[str, list[float]]) -> None:
    """Collect the decoded image's error against the raw one into ``stats``."""
    import numpy as np

    from visnav.msgs.image import image_to_numpy

    want = image_to_numpy(raw)
    got = image_to_numpy(decoded)
    if raw.encoding == "32FC1":
        ok = np.isfinite(want) & np.isfinite(got)
        for metres in (1.0, 3.0, 5.0):
            near = ok & (np.abs(want - metres) < 0.25)
            err = np.abs(got[near].astype(np.float64) - want[near]) * 1e3
            stats.setdefault(f"depth {metres:g} m", []).extend(err.tolist()[::50])
        lost = np.isfinite(want) & (want < 10.0) & ~np.isfinite(got)
        stats.setdefault("depth lost", []).append(float(lost.mean()))
    else:
        diff = got.astype(np.float64) - want.astype(np.float64)
        mse = float((diff**2).mean())
        stats.setdefault("colour mae", []).append(float(np.abs(diff).mean()))
        stats.setdefault("colour psnr", []).append(10 * np.log10(255.0**2 / max(mse, 1e-9)))


def _rerecord(
    bag: str, out: Path, start_s: float, seconds: float, policy: Any
) -> tuple[int, dict[str, Any]]:
    """Write the window of ``bag`` to ``out`` (images through ``policy``, None: raw)."""
    import numpy as np

    from visnav.bag import BagReader, BagWriter
    from visnav.bag.image_compression import (
        COMPRESSED_IMAGE,
        IMAGE,
        ImageCompression,
        decode_image,
    )
    from visnav.msgs.serde import deserialize

    cpu = {"compressed": [0.0, -1], "compressedDepth": [0.0, -1]}
    stats: dict[str, list[float]] = {}
    with BagReader(bag) as reader, BagWriter(out, compression="zstd") as writer:
        t0 = reader.start_ns + round(start_s * 1e9)
        ids: dict[str, int] = {}
        transports: dict[str, str] = {}
        for n, raw in enumerate(
            reader.raw_messages(start_ns=t0, stop_ns=t0 + round(seconds * 1e9))
        ):
            data: bytes | memoryview = raw.data
            topic, type_name = raw.topic, raw.type_name
            if policy is not None and type_name == IMAGE:
                if topic not in transports:
                    enc = str(deserialize(raw.data, IMAGE).encoding)
                    transports[topic] = ImageCompression.transport_for(enc)
                transport = transports[topic]
                if transport != "raw":
                    c0 = time.process_time()
                    data = policy.encode_cdr(raw.data, transport)
                    if cpu[transport][1] >= 0:  # the first frame (JIT warm-up) not counted
                        cpu[transport][0] += time.process_time() - c0
                    cpu[transport][1] += 1
                    topic, type_name = ImageCompression.topic(topic, transport), COMPRESSED_IMAGE
                    if n % 4 == 0:
                        _errors(
                            deserialize(raw.data, IMAGE),
                            decode_image(deserialize(data, COMPRESSED_IMAGE)),
                            stats,
                        )
            if topic not in ids:
                ids[topic] = writer.add_topic(topic, type_name)
            writer.write(ids[topic], raw.t_ns, data)
    size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    summary: dict[str, Any] = {
        k: float(np.median(v)) if k.startswith("colour") else v for k, v in stats.items()
    }
    summary["cpu"] = {k: v[0] / max(v[1], 1) * 1e3 for k, v in cpu.items()}
    return size, summary


def _from_bag(bag: str, start_s: float, seconds: float) -> None:
    import numpy as np

    from visnav.bag.image_compression import ImageCompression

    print(f"{bag}: {seconds:g} simulated s from {start_s:g} s, re-recorded (zstd MCAP chunks)")
    with tempfile.TemporaryDirectory(prefix="bench_image_bag_") as tmp:
        raw_size, _ = _rerecord(bag, Path(tmp) / "raw", start_s, seconds, None)
        print(f"  {'raw images (reference)':<30} {raw_size / seconds / 1e6:7.2f} MB per sim s")
        for i, (label, params) in enumerate(_POLICIES.items()):
            policy = ImageCompression.from_params(params)
            size, st = _rerecord(bag, Path(tmp) / f"policy{i}", start_s, seconds, policy)
            cpu = st.pop("cpu")
            print(
                f"  {label:<30} {size / seconds / 1e6:7.2f} MB per sim s  "
                f"{raw_size / size:5.2f}x smaller  encode CPU/frame JPEG "
                f"{cpu['compressed']:.1f} ms, depth {cpu['compressedDepth']:.1f} ms"
            )
            for metres in (1, 3, 5):
                err = np.asarray(st.get(f"depth {metres} m", []))
                if err.size == 0:
                    print(f"      depth at {metres} m: no pixels within 0.25 m in this window")
                    continue
                print(
                    f"      depth at {metres} m: error median {np.median(err):.2f} mm, "
                    f"p99 {np.percentile(err, 99):.2f} mm, max {err.max():.2f} mm "
                    f"({err.size} samples)"
                )
            lost = 100 * float(np.mean(st.get("depth lost", [0.0])))
            print(
                f"      valid depth < 10 m lost: {lost:.3f} %; colour: mean abs error "
                f"{st.get('colour mae', np.nan):.2f} / 255, PSNR {st.get('colour psnr', np.nan):.1f} dB"
            )


def main() -> None:
    """Run the benchmark and print the figures."""
    from visnav.bag.image_compression import image_transport_from_args

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=3.0, help="simulated s per run")
    parser.add_argument("--repeats", type=int, default=3, help="encode passes (median)")
    parser.add_argument("--ideal-sensors", action="store_true", help="also noise-free")
    parser.add_argument(
        "--runs", nargs=2, type=Path, metavar=("RAW_DIR", "COMPRESSED_DIR"), help="finished runs"
    )
    parser.add_argument(
        "--image-transport",
        nargs="+",
        default=None,
        metavar="NAME=VALUE",
        help="also a third run with these image_transport parameters (as visnav run's)",
    )
    parser.add_argument("--bag", default=None, help="a finished run's raw-image bag")
    parser.add_argument("--start", type=float, default=20.0, help="--bag: window start (s)")
    parser.add_argument("--seconds", type=float, default=5.0, help="--bag: window (sim s)")
    args = parser.parse_args()
    if args.bag is not None:
        _from_bag(args.bag, args.start, args.seconds)
        return
    if args.runs is not None:
        print(f"car runs {args.runs[0]} (raw images) and {args.runs[1]} (compressed):")
        _from_runs(*args.runs)
        _quantisation_error()
        return
    cases = [False, True] if args.ideal_sensors else [False]
    with tempfile.TemporaryDirectory(prefix="bench_image_bag_") as tmp:
        frames: dict[str, list[bytes]] = {}
        for ideal in cases:
            label = "ideal sensors" if ideal else "default sensor noise"
            rows: dict[str, dict[str, Any]] = {}
            kinds: list[tuple[str, bool, Any]] = [("raw images", True, None)]
            kinds.append(("compressed", False, None))
            if args.image_transport:
                policy = image_transport_from_args(args.image_transport)
                kinds.append((" ".join(args.image_transport), False, policy))
            for i, (what, raw, policy) in enumerate(kinds):
                name = f"run{i}{'_ideal' if ideal else ''}"
                s = _run(
                    Path(tmp) / name, raw=raw, duration=args.duration, ideal=ideal, transport=policy
                )
                rows[what] = s
                if raw and not ideal:
                    frames = _frames(s["bag"])
            print(f"car, {args.duration:g} simulated s, seed 0, no SLAM, {label}:")
            r = rows["raw images"]
            for what, s in rows.items():
                ratio = r["bag_bytes"] / s["bag_bytes"]
                verdict = "" if s is r else "(meets)" if ratio >= 8.0 else "(misses)"
                print(
                    f"  {what:<11} bag {s['bag_bytes'] / 1e6:8.2f} MB  "
                    f"{s['bag_mb_per_sim_s']:7.2f} MB per simulated s  RTF "
                    f"{s['real_time_factor']}  raw / this {ratio:.2f}x {verdict}"
                )
        print("\nencode cost per frame (the recorder's writer-thread job, this run's frames):")
        _encode_costs(frames, args.repeats)


if __name__ == "__main__":
    main()
