"""Image bags: bytes per simulated second with raw vs compressed images, and encode cost.

Run: ``python bench/bench_image_bag.py`` (``--duration S`` simulated seconds per run, default
3; ``--ideal-sensors`` also measures the noise-free cameras; ``--repeats N`` encode repeats).

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


def main() -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=3.0, help="simulated s per run")
    parser.add_argument("--repeats", type=int, default=3, help="encode passes (median)")
    parser.add_argument("--ideal-sensors", action="store_true", help="also noise-free")
    args = parser.parse_args()
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
