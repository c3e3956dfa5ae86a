"""Target detection over many images, in parallel, with a progress bar.

Parallel by threads, not processes: OpenCV's detectors release the GIL, so threads use every core
(2.2x on 2 cores for chessboards), and they avoid two process hazards measured here: a forked
worker can deadlock inside OpenCV once the parent's OpenCV thread pool has run, and the
forkserver/spawn start methods re-import the caller's ``__main__`` (breaking any script without
an ``if __name__ == "__main__"`` guard). While the workers run, OpenCV's own threading is set to
one thread per worker and restored afterwards.
"""

from __future__ import annotations

import ctypes
import os
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from .._shared.lazy import lazy_module
from .._shared.progress import Progress
from .targets import Detection, Target

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["ImageResult", "detect_images", "default_jobs", "available_memory", "workers_for_memory"]


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

#: Resident memory a detection worker may need per image pixel: measured ~630 MB for a 12 MP image
#: of a 28x17 board (findChessboardCornersSB's buffers), ~52 bytes a pixel; with margin.
BYTES_PER_PIXEL = 64
#: Below ``BYTES_PER_PIXEL`` times this many pixels (50 MP) of available memory per core, the
#: default number of workers is decided after the first image (detected alone) shows the size.
LARGEST_IMAGE_PIXELS = 50_000_000


def available_memory() -> int | None:
    """Bytes of memory available to new work (Linux ``MemAvailable``, else the free pages), or None
    when the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def workers_for_memory(jobs: int, image_size: tuple[int, int], available: int | None) -> int:
    """At most ``jobs`` workers, as many as the available memory holds for images of ``image_size``
    (at least one): many cores with large images must not run the machine out of memory."""
    if available is None:
        return jobs
    return max(1, min(jobs, available // (BYTES_PER_PIXEL * image_size[0] * image_size[1])))


def release_freed_memory() -> None:
    """Hand memory freed by image work back to the system (glibc's ``malloc_trim``; nothing
    elsewhere). Each worker thread's glibc arena keeps the pages of the images it decoded: after
    detecting 100 images of 5 MP on 2 threads ~550 MB stayed resident in the calling process (a
    ROS node, a notebook) until it exited; trimmed, what remains is what is still in use."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):  # not glibc (musl has no malloc_trim): nothing to do
        pass


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
        Worker threads (default: the available cores, and when memory is short no more than it
        holds for images the size of the first, which is then detected first); 1 runs in the
        calling thread with OpenCV's default internal threading.
    progress : bool
        Show a progress bar on stderr.
    """
    chosen = jobs is None
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    work: list[tuple[str, Target]] = [(str(p), target) for p in paths]
    bar = Progress(len(paths), "detecting", progress)
    results: list[ImageResult] = []
    try:
        available = available_memory() if chosen and jobs > 1 and len(paths) > jobs else None
        if available is not None and available < jobs * BYTES_PER_PIXEL * LARGEST_IMAGE_PIXELS:
            # memory may not hold every worker: the first image alone says how large the images
            # are, and so how many fit
            results.append(_detect_one(work[0]))
            bar.update()
            work = work[1:]
            if results[0].image_size is not None:
                fit = workers_for_memory(jobs, results[0].image_size, available)
                if fit < jobs and progress:
                    w, h = results[0].image_size
                    sys.stderr.write(f"detecting with {fit} worker(s) instead of {jobs}: images of {w}x{h} need about "
                                     f"{BYTES_PER_PIXEL * w * h / 2**30:.1f} GB each, {available / 2**30:.1f} GB available\n")
                jobs = fit
        if jobs == 1 or len(work) < 2:
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
        release_freed_memory()
    return results
