"""mp4 writers of :func:`raspv_bags.render.render_bag`, fed from a queue by a thread (encoding
overlaps the simulation; both encoders release the GIL while they encode). No ROS imports.

- ``mp4v`` (default, no extra): OpenCV's ``VideoWriter`` with its own FFmpeg, MPEG-4 Part 2;
  plays in VLC, mpv and most desktop players, not in web browsers.
- ``h264``: H.264 (libx264, yuv420p) through the FFmpeg binary of ``imageio-ffmpeg`` (the
  ``video`` extra): plays everywhere, browsers included, and is smaller. Odd sizes are padded by
  one black pixel row/column (yuv420p needs even ones).

Frames are BGR ``uint8`` (H, W, 3) or grey (H, W), all of one size.
"""
from __future__ import annotations

import queue
import threading
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

CODECS = ("mp4v", "h264")
H264_CRF = 20   # x264's constant rate factor: 0 lossless … 51 worst; 18–23 look the same to most eyes


class VideoError(ValueError):
    """A video that cannot be written (the message says why)."""


def require_codec(codec: str) -> None:
    """Raise :class:`VideoError` for an unknown codec, and
    :class:`~raspv_common.extras.MissingExtra` (one line with the install command) when the
    codec's extra is not installed."""
    if codec not in CODECS:
        raise VideoError(f"unknown video codec {codec!r} (known: {', '.join(CODECS)})")
    if codec == "h264":
        from raspv_common.extras import require

        require("imageio_ffmpeg", "an H.264 video (raspv render --codec h264)")


class VideoSink:
    """Writes frames to ``path`` at ``fps`` [Hz] with ``codec`` (see the module docstring)."""

    def __init__(self, path: Path, fps: float, size: tuple[int, int], color: bool, codec: str = "mp4v") -> None:
        require_codec(codec)
        path.parent.mkdir(parents=True, exist_ok=True)
        self.size = size                       # (width, height) [px] of the frames given
        self._encode: Callable[[np.ndarray], None]
        self._finish: Callable[[], None]
        if codec == "mp4v":
            writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size, isColor=color)
            if not writer.isOpened():
                raise VideoError(f"{path}: OpenCV cannot write an mp4 video here (mp4v codec)")
            self._encode, self._finish = writer.write, writer.release
        else:
            self._open_h264(path, fps, size, color)
        self.q: queue.Queue = queue.Queue(maxsize=8)
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="video", daemon=True)
        self.thread.start()

    def _open_h264(self, path: Path, fps: float, size: tuple[int, int], color: bool) -> None:
        import imageio_ffmpeg

        w, h = size
        pad_w, pad_h = w % 2, h % 2
        writer = imageio_ffmpeg.write_frames(
            str(path), (w + pad_w, h + pad_h), pix_fmt_in="bgr24" if color else "gray", pix_fmt_out="yuv420p",
            fps=fps, codec="libx264", macro_block_size=1, ffmpeg_log_level="error",
            output_params=["-crf", str(H264_CRF), "-movflags", "+faststart"])
        try:
            writer.send(None)  # starts ffmpeg
        except (OSError, RuntimeError) as exc:
            raise VideoError(f"{path}: ffmpeg cannot write an H.264 video here ({exc})") from None

        def encode(frame: np.ndarray) -> None:
            if pad_w or pad_h:
                pad = ((0, pad_h), (0, pad_w)) + (((0, 0),) if frame.ndim == 3 else ())
                frame = np.pad(frame, pad)
            writer.send(np.ascontiguousarray(frame))

        self._encode, self._finish = encode, writer.close

    def _run(self) -> None:
        while True:
            frame = self.q.get()
            if frame is None:
                return
            if self.error is not None:
                continue  # keep draining so the producer never blocks
            try:
                self._encode(frame)
            except (OSError, RuntimeError, ValueError, cv2.error) as exc:
                self.error = exc

    def write(self, frame: np.ndarray) -> None:
        if frame.shape[1::-1] != self.size:
            raise VideoError(f"frame size changed from {self.size} to {frame.shape[1::-1]}")
        self.q.put(frame)

    def close(self) -> None:
        self.q.put(None)
        self.thread.join()
        try:
            self._finish()
        except (OSError, RuntimeError) as exc:
            self.error = self.error or exc
        if self.error is not None:
            raise VideoError(f"video encoding failed: {self.error}")
