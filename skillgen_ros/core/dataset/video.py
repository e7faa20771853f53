"""Short MP4 clips of attempts (front camera) so a person can see what went wrong."""
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


def write_mp4(path: str, frames: Sequence[np.ndarray], fps: float = 20.0) -> str:
    """Encode RGB uint8 frames (all the same HxWx3) with OpenCV's mp4v codec."""
    if len(frames) == 0:
        raise InvalidInputError(f"{path}: no frames to write")
    first = np.asarray(frames[0])
    if first.ndim != 3 or first.shape[2] != 3:
        raise InvalidInputError(f"{path}: frames must be HxWx3 RGB, got {first.shape}")
    h, w = first.shape[:2]
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (w, h))
    if not writer.isOpened():
        raise InvalidInputError(f"{path}: OpenCV cannot open an mp4v writer", reason="OUTPUT_NOT_WRITABLE")
    try:
        for i, fr in enumerate(frames):
            fr = np.asarray(fr)
            if fr.shape != first.shape:
                raise InvalidInputError(f"{path}: frame {i} is {fr.shape}, expected {first.shape}")
            writer.write(cv2.cvtColor(fr.astype(np.uint8), cv2.COLOR_RGB2BGR))
    finally:
        writer.release()
    return str(path)


def attempt_clip(path: str, clips: Sequence[tuple[str, bool, Sequence[np.ndarray]]], fps: float = 20.0,
                 size: tuple[int, int] | None = None) -> str:
    """One MP4 of several attempts in a row, each captioned: (label, success, RGB frames)."""
    out = []
    for label, ok, frames in clips:
        for fr in frames:
            fr = np.asarray(fr, np.uint8)
            if size is not None:
                fr = cv2.resize(fr, size, interpolation=cv2.INTER_NEAREST)
            out.append(caption(fr, f"{label} {'OK' if ok else 'FAILED'}", ok))
    return write_mp4(path, out, fps)
