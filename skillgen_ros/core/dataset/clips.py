"""A run's videos: the first attempts in one MP4, and one clip per outcome (each failure reason
and a success) for report.html. Clips are re-rendered from the dataset arrays (render.py)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Sequence

from ..generation.attempt import AttemptResult
from .render import ClipSpec, EpisodeRenderer
from .video import Mp4Writer, caption, write_mp4

CLIP_DIR = "clips"
ATTEMPTS_FPS = 10.0


@dataclass(frozen=True)
class RunVideos:
    attempts_mp4: str = ""  # path of the first attempts in a row ("" = none)
    clips: dict = field(default_factory=dict)  # attempt index -> clip path
    examples: dict = field(default_factory=dict)  # reason ("OK" for a success) -> attempt index


def example_attempts(results: Sequence[AttemptResult]) -> dict[str, int]:
    """The first attempt of each outcome: reason -> attempt index (a success under "OK")."""
    out: dict[str, int] = {}
    for r in results:
        out.setdefault(r.reason.value, r.index)
    return out


def write_run_videos(out_dir: str, task: str, variant: str, results: Sequence[AttemptResult], first_n: int,
                     spec: ClipSpec = ClipSpec()) -> RunVideos:
    """Render the first `first_n` attempts and one example per outcome; write attempts.mp4 and clips/.
    Each attempt is rendered once and streamed into its files (memory: one attempt's frames)."""
    if first_n <= 0 or not results:
        return RunVideos()
    examples = example_attempts(results)
    firsts = {r.index for r in results[:first_n]}
    wanted = [r for r in results if r.index in set(examples.values()) | firsts]
    clips = {}
    renderer = EpisodeRenderer(spec)
    attempts = Mp4Writer(os.path.join(out_dir, "attempts.mp4"), ATTEMPTS_FPS)
    try:
        for r in wanted:
            frames, fps = renderer.render(task, variant, r.scene_seed, r.episode)
            label = f"attempt {r.index} {'OK' if r.success else r.reason.value}"
            captioned = [caption(f, label, r.success) for f in frames]
            path = os.path.join(out_dir, CLIP_DIR, f"attempt_{r.index}.mp4")
            clips[r.index] = write_mp4(path, captioned, fps)
            if r.index in firsts:
                for f in captioned:
                    attempts.add(f)
    finally:
        renderer.close()
        path = attempts.close() if attempts.frames else ""
    return RunVideos(path, clips, examples)
