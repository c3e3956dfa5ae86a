"""Target detection over many images, in parallel, with a progress bar.

Parallel by threads, not processes: OpenCV's detectors release the GIL, so threads use every core
(2.2x on 2 cores for chessboards), and they avoid two process hazards measured here: a forked
worker can deadlock inside OpenCV once the parent's OpenCV thread pool has run, and the
forkserver/spawn start methods re-import the caller's ``__main__`` (breaking any script without
an ``if __name__ == "__main__"`` guard). While the workers run, OpenCV's own threading is set to
one thread per worker and restored afterwards.

Detections can be kept in a cache (:func:`detection_cache_dir`), keyed by the image file's bytes,
the target and the detector's version: running ``check`` and then ``calibrate`` on the same
session, or calibrating again with other options, does not detect again, and gives the very same
corners (they are what the detector returned, stored as they were).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence, cast

import numpy as np

from ..._shared.lazy import lazy_module
from ..._shared.progress import Progress
from ..._version import __version__
from . import preview
from .targets import Detection, Target

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["ImageResult", "detect_images", "default_jobs", "available_memory", "workers_for_memory",
           "detection_cache_dir", "default_cache_dir", "CACHE_ENV", "unchanged_files_remembered"]


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


#: The environment variable naming the folder detections are cached in; unset or empty: no cache.
#: The command line sets it to :func:`default_cache_dir` unless it is set (``--no-cache``: empty).
CACHE_ENV = "HANDEYE_CACHE_DIR"
#: Part of every cache key: raise it when detection returns something else for the same image.
DETECTION_VERSION = 3


def default_cache_dir() -> Path:
    """The user's cache folder for handeye (``$XDG_CACHE_HOME/handeye``, ``~/.cache/handeye``;
    ``%LOCALAPPDATA%\\handeye\\cache`` on Windows, ``~/Library/Caches/handeye`` on macOS)."""
    if sys.platform.startswith("win"):
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
        return base / "handeye" / "cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "handeye"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "handeye"


def detection_cache_dir() -> Path | None:
    """Where detections are cached (the folder of :data:`CACHE_ENV`, under ``detections/``), or
    None when caching is off."""
    root = os.environ.get(CACHE_ENV, "")
    return Path(root) / "detections" if root else None


def _cache_key(data: bytes, target: Target) -> str | None:
    """The cache key of detecting ``target`` in an image file of bytes ``data``: None for a target
    class defined outside handeye (its code may change with nothing here knowing)."""
    if not type(target).__module__.startswith("handeye."):
        return None
    h = hashlib.blake2b(data, digest_size=20)
    h.update(f"|{type(target).__module__}.{type(target).__qualname__}|{target!r}|opencv {cv2.__version__}"
             f"|handeye {__version__}|detection {DETECTION_VERSION}".encode())
    return h.hexdigest()


def _cached(folder: Path, key: str, path: str) -> ImageResult | None:
    """The result stored under ``key``, or None (absent, or unreadable: detected again)."""
    try:
        with np.load(folder / key[:2] / f"{key}.npz", allow_pickle=False) as z:
            size = cast(tuple[int, int], tuple(int(v) for v in z["image_size"]))
            if not bool(z["found"]):
                return ImageResult(Path(path), None, size, str(z["error"]))
            det = Detection(z["ids"].astype(np.intp), z["image_points"], z["object_points"])
            return ImageResult(Path(path), det, size, None)
    except Exception:  # noqa: BLE001 - any damaged entry (truncated, foreign) is only a cache miss
        return None


def _store(folder: Path, key: str, result: ImageResult) -> None:
    """Keep ``result`` under ``key`` (atomically; a cache that cannot be written is skipped)."""
    det = result.detection
    arrays: dict[str, Any] = dict(image_size=np.array(result.image_size), found=np.array(det is not None),
                                  error=np.array(result.error or ""))
    if det is not None:
        arrays.update(ids=np.asarray(det.ids), image_points=np.asarray(det.image_points),
                      object_points=np.asarray(det.object_points))
    try:
        sub = folder / key[:2]
        sub.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=sub, suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **arrays)
            os.replace(tmp, sub / f"{key}.npz")
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except OSError:
        pass


_REMEMBER: ContextVar[bool] = ContextVar("_REMEMBER", default=False)
#: (path, size, modification time in ns, inode, the target) -> what detection made of that file, in this process
_SEEN: dict[tuple, ImageResult] = {}
_SEEN_LOCK = threading.Lock()
#: At most this many files remembered (a capture's images; the oldest forgotten first).
SEEN_MAX = 2000


@contextmanager
def unchanged_files_remembered() -> Iterator[None]:
    """Within it, an image file that this process detected before (in any call within it) and that is
    unchanged since (the same path, size, modification time to the nanosecond and inode) is not read
    again: its detection is remembered (the cache on disk would read and hash the whole file first).
    For a process that calibrates a growing capture again and again, whose images are written once and
    never changed: ``handeye live``'s calibration process (20 views of 1280x1024: 12 MB read and
    hashed before every calibration)."""
    token = _REMEMBER.set(True)
    try:
        yield
    finally:
        _REMEMBER.reset(token)


def _file_state(path: str, target: Target) -> tuple | None:
    """What says a file is unchanged since it was detected (None: unreadable)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (os.path.abspath(path), st.st_size, st.st_mtime_ns, st.st_ino, type(target).__module__, type(target).__qualname__, repr(target))


def _detect_one(args: tuple[str, Target, Path | None, bool, bool]) -> ImageResult:
    path, target, cache, keep_preview, remember = args
    state = _file_state(path, target) if remember and not keep_preview else None
    if state is not None and (seen := _SEEN.get(state)) is not None:
        return seen
    result = _detect_stored(path, target, cache, keep_preview)
    if state is not None and result.image_size is not None:
        with _SEEN_LOCK:
            if len(_SEEN) >= SEEN_MAX:
                _SEEN.pop(next(iter(_SEEN)))
            _SEEN[state] = result
    return result


def _detect_stored(path: str, target: Target, cache: Path | None, keep_preview: bool) -> ImageResult:
    """The detection of one image, from the cache on disk when it holds it (kept there when not)."""
    key = None
    if cache is not None:
        try:
            key = _cache_key(Path(path).read_bytes(), target)
        except OSError:  # unreadable: imread below says so
            key = None
        if key is not None and (hit := _cached(cache, key, path)) is not None:
            return hit
    result = _detect_uncached(path, target, keep_preview)
    if cache is not None and key is not None and result.image_size is not None and min(result.image_size) >= MIN_IMAGE_SIDE:
        _store(cache, key, result)
    return result


def _detect_uncached(path: str, target: Target, keep_preview: bool = False) -> ImageResult:
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
    if det is not None and keep_preview:  # the report's thumbnail, cut while the image is decoded
        preview.remember(path, preview.cut(gray, np.asarray(det.image_points)))
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

    Detections are read from and kept in the cache of :func:`detection_cache_dir` when it is on.
    """
    chosen = jobs is None
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    cache = detection_cache_dir()
    previews = preview.wanted()
    remember = _REMEMBER.get()  # read here: the workers' threads do not see this context
    work: list[tuple[str, Target, Path | None, bool, bool]] = [(str(p), target, cache, k < previews, remember)
                                                                for k, p in enumerate(paths)]
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
