"""Short MP4 clips of attempts (front camera) so a person can see what went wrong.

H.264 (libx264, yuv420p, +faststart) through the ffmpeg binary that imageio-ffmpeg bundles in its
wheel: what Chrome and Firefox play (OpenCV's mp4v, MPEG-4 Part 2, they do not).
"""
from __future__ import annotations

import os
from typing import Sequence

import cv2
import numpy as np

from ..errors import InvalidInputError


def caption(frame: np.ndarray, text: str, ok: bool | None = None) -> np.ndarray:
    """Copy of an RGB frame with a caption bar (green success, red failure, white otherwise)."""
    img = np.ascontiguousarray(np.asarray(frame, np.uint8)).copy()
    color = (255, 255, 255) if ok is None else ((40, 200, 40) if ok else (230, 40, 40))
    scale = max(0.3, img.shape[0] / 400)
    cv2.rectangle(img, (0, 0), (img.shape[1], int(22 * scale) + 4), (0, 0, 0), -1)
    cv2.putText(img, text, (3, int(18 * scale)), cv2.FONT_HERSHEY_SIMPLEX, 0.5 * scale, color, 1, cv2.LINE_AA)
    return img


class Mp4Writer:
    """Streamed H.264 MP4 (frames are sent as they come: a run's clips never sit in memory together).
    All frames must be the first one's HxWx3; odd sides are padded to even (yuv420p)."""

    def __init__(self, path: str, fps: float = 20.0):
        self.path, self.fps = str(path), float(fps)
        self._writer = None
        self._shape: tuple | None = None
        self.frames = 0

    def _open(self, shape: tuple) -> None:
        import imageio_ffmpeg

        h, w = shape[:2]
        self._pad = (h + h % 2, w + w % 2)
        try:
            os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
            self._writer = imageio_ffmpeg.write_frames(
                self.path, (self._pad[1], self._pad[0]), fps=self.fps, codec="libx264", pix_fmt_in="rgb24",
                pix_fmt_out="yuv420p", macro_block_size=1, ffmpeg_log_level="error",
                output_params=["-movflags", "+faststart", "-preset", "veryfast", "-crf", "23"])
            self._writer.send(None)
        except (OSError, RuntimeError) as e:
            raise InvalidInputError(f"{self.path}: cannot write the MP4: {e}", reason="OUTPUT_NOT_WRITABLE") from None
        self._shape = shape

    def add(self, frame: np.ndarray) -> None:
        fr = np.asarray(frame)
        if self._shape is None:
            if fr.ndim != 3 or fr.shape[2] != 3:
                raise InvalidInputError(f"{self.path}: frames must be HxWx3 RGB, got {fr.shape}")
            self._open(fr.shape)
        elif fr.shape != self._shape:
            raise InvalidInputError(f"{self.path}: frame {self.frames} is {fr.shape}, expected {self._shape}")
        img = np.zeros(self._pad + (3,), np.uint8)
        img[:fr.shape[0], :fr.shape[1]] = fr.astype(np.uint8)
        self._writer.send(np.ascontiguousarray(img).tobytes())
        self.frames += 1

    def close(self) -> str:
        if self._writer is None:
            raise InvalidInputError(f"{self.path}: no frames to write")
        self._writer.close()
        self._writer = None
        return self.path


def write_mp4(path: str, frames: Sequence[np.ndarray], fps: float = 20.0) -> str:
    """Encode RGB uint8 frames (all the same HxWx3; odd sizes are padded to even) as H.264 MP4."""
    if len(frames) == 0:
        raise InvalidInputError(f"{path}: no frames to write")
    first = np.asarray(frames[0])
    for i, fr in enumerate(frames):  # check everything before a file exists
        if np.asarray(fr).shape != first.shape:
            raise InvalidInputError(f"{path}: frame {i} is {np.asarray(fr).shape}, expected {first.shape}")
    w = Mp4Writer(path, fps)
    try:
        for fr in frames:
            w.add(fr)
    finally:
        if w.frames:
            w.close()
    return str(path)


def attempt_clip(path: str, clips: Sequence[tuple[str, bool, Sequence[np.ndarray]]], fps: float = 20.0,
                 size: tuple[int, int] | None = None) -> str:
    """One MP4 of several attempts in a row, each captioned: (label, success, RGB frames)."""
    out = []
    for label, ok, frames in clips:
        for fr in frames:
            fr = np.asarray(fr, np.uint8)
            if size is not None:
                fr = cv2.resize(fr, size, interpolation=cv2.INTER_AREA)
            out.append(caption(fr, f"{label} {'OK' if ok else 'FAILED'}", ok))
    return write_mp4(path, out, fps)
