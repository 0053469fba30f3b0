"""One phosphene frame ready to send: raw pixels, or PNG when it is clearly smaller.

PNG is written with no row filter and zlib level 2: on an 800×800 phosphene image (Gaussian
dots on a hexagonal grid) this takes ≈ 2.8 ms and gives ≈ 90 KB (7× smaller than raw), where
OpenCV's default filters take 7–10 ms for a bigger file (``raspv bench hmd --codecs``).
A frame whose PNG is not at least :data:`PNG_WORTH` smaller than raw goes out raw (the
format byte of each frame tells the client). An rgb8 frame whose red and blue channels are
empty (the spv node's green output for headsets) travels as its green channel with the
``FLAG_GREEN`` flag: a third of the bytes.
"""
from __future__ import annotations

import threading

import cv2
import numpy as np

from raspv_hmd.protocol import FLAG_GREEN, FORMAT_LEVELS, FORMAT_PNG, FORMAT_RAW, FrameHeader, pack_frame_header

PNG_PARAMS = [cv2.IMWRITE_PNG_COMPRESSION, 2, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
PNG_WORTH = 0.75                # PNG is used only when it is below this fraction of the raw size
MAX_SIDE = 8192                 # px; larger images are refused


def check_image(image: np.ndarray) -> np.ndarray:
    """A phosphene image (H, W) mono8 or (H, W, 3) rgb8 uint8 → C-contiguous; ValueError otherwise."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        raise ValueError(f"a phosphene frame must be a uint8 array, got {getattr(image, 'dtype', type(image).__name__)}")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise ValueError(f"a phosphene frame must be (H, W) mono8 or (H, W, 3) rgb8, got shape {image.shape}")
    h, w = image.shape[:2]
    if not (0 < h <= MAX_SIDE and 0 < w <= MAX_SIDE):
        raise ValueError(f"a phosphene frame must be 1..{MAX_SIDE} px on each side, got {w}x{h}")
    return np.ascontiguousarray(image)


class OutgoingFrame:
    """A submitted frame; encodings are made once, on first use, and shared by all clients."""

    def __init__(self, seq: int, image: np.ndarray, stamp: float) -> None:
        self.seq = seq
        self.image = check_image(image)
        self.stamp = float(stamp)
        self.height, self.width = self.image.shape[:2]
        self.flags = 0
        if self.image.ndim == 3 and not self.image[..., 0].any() and not self.image[..., 2].any():
            self.image = np.ascontiguousarray(self.image[..., 1])
            self.flags = FLAG_GREEN
        self.channels = 1 if self.image.ndim == 2 else 3
        self._payloads: dict[int, tuple[int, bytes]] = {}
        self._lock = threading.Lock()

    def payload(self, wanted: int) -> tuple[int, bytes]:
        """(format actually used, payload bytes) for the ``wanted`` format."""
        with self._lock:
            if wanted not in self._payloads:
                self._payloads[wanted] = self._encode(wanted)
            return self._payloads[wanted]

    def _encode(self, wanted: int) -> tuple[int, bytes]:
        if wanted == FORMAT_PNG:
            img = self.image if self.channels == 1 else cv2.cvtColor(self.image, cv2.COLOR_RGB2BGR)
            ok, png = cv2.imencode(".png", img, PNG_PARAMS)
            if ok and png.size < PNG_WORTH * self.image.size:
                return FORMAT_PNG, png.tobytes()
        if FORMAT_RAW not in self._payloads:
            self._payloads[FORMAT_RAW] = (FORMAT_RAW, self.image.tobytes())
        return self._payloads[FORMAT_RAW]

    def message(self, wanted: int, sent: float) -> tuple[int, bytes]:
        """(format used, the whole frame message: header + payload) stamped ``sent`` (s)."""
        fmt, payload = self.payload(wanted)
        header = pack_frame_header(FrameHeader(fmt, self.channels, self.width, self.height, self.seq,
                                               len(payload), self.stamp, sent, self.flags))
        return fmt, header + payload


class LevelsFrame:
    """A submitted frame of the levels stream: its payload (:mod:`raspv_hmd.levels_stream`) is
    the same for every client; only the header's send time differs."""

    def __init__(self, seq: int, map_id: int, payload: bytes, stamp: float, width: int, height: int,
                 green: bool = False) -> None:
        self.seq, self.map_id, self.payload, self.stamp = seq, map_id, payload, float(stamp)
        self.width, self.height, self.flags = width, height, FLAG_GREEN if green else 0

    def message(self, _wanted: int, sent: float) -> tuple[int, bytes]:
        """(FORMAT_LEVELS, the whole frame message) stamped ``sent`` (s)."""
        header = pack_frame_header(FrameHeader(FORMAT_LEVELS, 1, self.width, self.height, self.seq,
                                               len(self.payload), self.stamp, sent, self.flags))
        return FORMAT_LEVELS, header + self.payload
