"""Image bags: bytes per simulated second with raw vs compressed images, and encode cost.

Run: ``python bench/bench_image_bag.py`` (``--duration S`` simulated seconds per run, default
3; ``--ideal-sensors`` also measures the noise-free cameras; ``--repeats N`` encode repeats).
``--runs RAW_DIR COMPRESSED_DIR`` reads two finished runs instead (e.g. 30 s runs made with
``visnav run car --duration 30 --record-images [--raw-images] --out DIR``, which take ~17 min
each on a loaded 2-core machine) and prints the same figure with the bytes per frame of each
image topic; it also prints compressedDepth's quantisation error at 1, 3 and 5 m.

* Bag size: two short car runs in this process, ``visnav run car --record-images
  --raw-images`` (the reference: images as published, zstd MCAP chunks as every run's bag)
  and ``--record-images`` (``<topic>/compressed`` JPEG, ``<topic>/compressedDepth`` PNG),
  same seed, no SLAM. Figure: bag bytes per simulated second (the summary's
  ``bag_mb_per_sim_s``) and the ratio raw / compressed (goal >= 8). The first half second
  (start-up, before the cameras render) is part of both.
* Encode cost: the recorder's job per frame (CDR Image -> CompressedImage CDR, on its
  writer thread) on the raw run's own frames, median of ``--repeats`` passes, per topic, as
  wall and CPU (process) time (CPU is what it costs on a loaded machine); the decode CPU time
  of the readers (view, doctor, slam, bag play --decompress); and the compressedDepth PNG at
  zlib levels 1 (the plugin's default) and 9, for size/time.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any


def _run(out: Path, *, raw: bool, duration: float, ideal: bool) -> dict[str, Any]:
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

    policies = {"default": ImageCompression(), "png9": ImageCompression(depth_png_level=9)}
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


def main() -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=3.0, help="simulated s per run")
    parser.add_argument("--repeats", type=int, default=3, help="encode passes (median)")
    parser.add_argument("--ideal-sensors", action="store_true", help="also noise-free")
    parser.add_argument(
        "--runs", nargs=2, type=Path, metavar=("RAW_DIR", "COMPRESSED_DIR"), help="finished runs"
    )
    args = parser.parse_args()
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
            rows = {}
            for raw in (True, False):
                name = f"{'raw' if raw else 'compressed'}{'_ideal' if ideal else ''}"
                s = _run(Path(tmp) / name, raw=raw, duration=args.duration, ideal=ideal)
                rows[raw] = s
                if raw and not ideal:
                    frames = _frames(s["bag"])
            r, c = rows[True], rows[False]
            print(f"car, {args.duration:g} simulated s, seed 0, no SLAM, {label}:")
            for what, s in (("raw images", r), ("compressed", c)):
                print(
                    f"  {what:<11} bag {s['bag_bytes'] / 1e6:8.2f} MB  "
                    f"{s['bag_mb_per_sim_s']:7.2f} MB per simulated s  RTF {s['real_time_factor']}"
                )
            ratio = r["bag_bytes"] / c["bag_bytes"]
            verdict = "meets" if ratio >= 8.0 else "misses"
            print(f"  ratio raw / compressed: {ratio:.1f}x ({verdict} the goal >= 8x)")
        print("\nencode cost per frame (the recorder's writer-thread job, this run's frames):")
        _encode_costs(frames, args.repeats)


if __name__ == "__main__":
    main()
