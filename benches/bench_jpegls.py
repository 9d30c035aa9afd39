"""JPEG-LS decoding (FLIR CSQ frames): irfidelity's own decoder against CharLS and ffmpeg.

    python benches/bench_jpegls.py [--frames 50] [--repeat 5]

The frames are a real 640x512 FLIR frame (tests/data/radiometric, 16-bit counts), moved a few
columns and given its own sensor noise (σ 6 counts) per frame, coded lossless by CharLS, and
put into a CSQ file (FFF frames one after another, as FLIR writes them). One core throughout.
Measured in the same run, per frame, best of ``--repeat``:

* irfidelity ``load_frame(csq, page=k)``: the user's path (the file read, the FFF frame
  parsed, the JPEG-LS decoded, the array returned);
* CharLS (imagecodecs ``jpegls_decode``) on the stream already in memory, and with the
  frame's bytes read from the file first (the same work as irfidelity's path);
* ffmpeg (when on PATH): the frames as .jls files decoded in one ``ffmpeg -threads 1`` run to
  raw 16-bit samples (the extraction route FLIR video users take), per frame.

Issue 39's goal: irfidelity ≤ 1.5× CharLS on one core, and faster than ffmpeg per frame. A
benchmark, not a test: numbers depend on the machine.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent / "tests"))
import imagecodecs
from _common import best
from flir_records import Frame, jpegls

import irfidelity as irf

SOURCE = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data" / "radiometric" / "flirpy_frame_000000.fff"
GOAL = 1.5  # irfidelity's time / CharLS's, at most


def make_csq(root: pathlib.Path, frames: int) -> tuple[pathlib.Path, list[bytes]]:
    source = Frame.parse(SOURCE.read_bytes())
    counts = irf.load_frame(SOURCE).astype(np.float64)
    rng = np.random.default_rng(39)
    streams = []
    for k in range(frames):
        frame = np.roll(counts, k % 7, axis=1) + rng.normal(0, 6, counts.shape)
        streams.append(jpegls(np.clip(np.rint(frame), 0, 65535).astype(np.uint16)))
    path = root / "recording.csq"
    path.write_bytes(b"".join(source.with_raw_image(s).to_bytes() for s in streams))
    return path, streams


def per_frame(fn, frames: int, repeat: int) -> float:
    return best(fn, repeat) / frames


def ffmpeg_per_frame(root: pathlib.Path, streams: list[bytes], repeat: int) -> float | None:
    if shutil.which("ffmpeg") is None:
        return None
    for k, stream in enumerate(streams):
        (root / f"f{k:05d}.jls").write_bytes(stream)
    command = ["ffmpeg", "-loglevel", "error", "-threads", "1", "-f", "image2", "-c:v", "jpegls",
               "-i", str(root / "f%05d.jls"), "-threads", "1", "-f", "rawvideo", "-pix_fmt", "gray16le", "-"]

    def run() -> None:
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)

    return per_frame(run, len(streams), repeat)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=50)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp)
        path, streams = make_csq(root, args.frames)
        first = irf.load_frame(path, page=0)
        assert np.array_equal(first, imagecodecs.jpegls_decode(streams[0]))  # the same counts
        size = sum(map(len, streams)) / len(streams)
        print(f"{args.frames} frames of {first.shape[1]}x{first.shape[0]} uint16, {size / 1024:.0f} KiB each coded "
              f"({first.nbytes / size:.2f}:1)")
        offsets = np.cumsum([0] + [len(source) for source in (
            Frame.parse(SOURCE.read_bytes()).with_raw_image(s).to_bytes() for s in streams)])

        def irfidelity_frames() -> None:
            for k in range(args.frames):
                irf.load_frame(path, page=k)

        def charls_in_memory() -> None:
            for stream in streams:
                imagecodecs.jpegls_decode(stream)

        def charls_from_file() -> None:
            with open(path, "rb") as f:
                for k in range(args.frames):
                    f.seek(int(offsets[k]))
                    frame = f.read(int(offsets[k + 1] - offsets[k]))
                    imagecodecs.jpegls_decode(frame[frame.index(b"\xff\xd8\xff"):])

        t0 = time.perf_counter()
        ours = per_frame(irfidelity_frames, args.frames, args.repeat)
        memory = per_frame(charls_in_memory, args.frames, args.repeat)
        from_file = per_frame(charls_from_file, args.frames, args.repeat)
        ffmpeg = ffmpeg_per_frame(root, streams, args.repeat)
        print(f"irfidelity load_frame (file, FFF, JPEG-LS): {ours * 1e3:7.2f} ms a frame")
        print(f"CharLS, stream in memory                  : {memory * 1e3:7.2f} ms a frame")
        print(f"CharLS, frame read from the file          : {from_file * 1e3:7.2f} ms a frame")
        if ffmpeg is None:
            print("ffmpeg                                    :  not on PATH (apt install ffmpeg), not measured")
        else:
            print(f"ffmpeg, .jls files in one run             : {ffmpeg * 1e3:7.2f} ms a frame")
        print(f"ratio: irfidelity / CharLS = {ours / from_file:.2f} (file), {ours / memory:.2f} (in memory); "
              f"goal <= {GOAL}" + ("" if ffmpeg is None else f"; ffmpeg / irfidelity = {ffmpeg / ours:.2f}"))
        print(f"({time.perf_counter() - t0:.1f} s measuring, one core)")


if __name__ == "__main__":
    main()
