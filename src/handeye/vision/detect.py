"""Target detection over many images, in parallel, with a progress bar.

Parallel by threads, not processes: OpenCV's detectors release the GIL, so threads use every core
(2.2x on 2 cores for chessboards), and they avoid two process hazards measured here: a forked
worker can deadlock inside OpenCV once the parent's OpenCV thread pool has run, and the
forkserver/spawn start methods re-import the caller's ``__main__`` (breaking any script without
an ``if __name__ == "__main__"`` guard). While the workers run, OpenCV's own threading is set to
one thread per worker and restored afterwards.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

from .._shared.lazy import lazy_module
from .._shared.progress import Progress
from .targets import Detection, Target

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["ImageResult", "detect_images", "default_jobs"]


@dataclass(frozen=True)
class ImageResult:
    """What detection made of one image: the detection, or why there is none."""

    path: Path
    detection: Detection | None
    image_size: tuple[int, int] | None  #: (width, height); None when unreadable
    error: str | None = None  #: why there is no detection: unreadable, too small, detector failed, target not found


def default_jobs() -> int:
    """Workers by default: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


#: Images smaller than this on a side are not given to the detectors (OpenCV's asserts on them).
MIN_IMAGE_SIDE = 32


def _detect_one(args: tuple[str, Target]) -> ImageResult:
    path, target = args
    gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if gray is None:
        return ImageResult(Path(path), None, None, "unreadable (missing, corrupt, or not an image format OpenCV reads)")
    size = (gray.shape[1], gray.shape[0])
    if min(size) < MIN_IMAGE_SIDE:
        return ImageResult(Path(path), None, size, f"image of {size[0]}x{size[1]} px: too small for the detector "
                           f"(at least {MIN_IMAGE_SIDE} px a side)")
    try:
        det = target.detect(gray)
    except cv2.error as exc:  # an image the detector cannot take: skipped with the reason, not a crash
        reason = (str(exc).strip().splitlines() or ["OpenCV error"])[-1]
        return ImageResult(Path(path), None, size, f"the detector failed on it ({reason})")
    return ImageResult(Path(path), det, size, None if det is not None else "target not found")


def detect_images(
    paths: Sequence[str | Path], target: Target, jobs: int | None = None, progress: bool = True
) -> list[ImageResult]:
    """Detect ``target`` in every image, in order; never raises for a bad image (see ``error``).

    Parameters
    ----------
    paths : sequence of paths
    target : Target
    jobs : int, optional
        Worker threads (default: the available cores); 1 runs in the calling thread with
        OpenCV's default internal threading.
    progress : bool
        Show a progress bar on stderr.
    """
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    work: Iterable[tuple[str, Target]] = [(str(p), target) for p in paths]
    bar = Progress(len(paths), "detecting", progress)
    results: list[ImageResult] = []
    try:
        if jobs == 1 or len(paths) < 2:
            for item in work:
                results.append(_detect_one(item))
                bar.update()
        else:
            saved = cv2.getNumThreads()
            cv2.setNumThreads(1)
            try:
                with ThreadPoolExecutor(max_workers=min(jobs, len(paths))) as pool:
                    for res in pool.map(_detect_one, work):
                        results.append(res)
                        bar.update()
            finally:
                cv2.setNumThreads(saved)
    finally:
        bar.close()
    return results
