"""Camera images of ``simrun serve``: encoded off the simulation thread, as JPEG or PNG.

The loop thread only copies a frame's pixels (:meth:`ImageEncoder.put`); the encoder thread turns them into
the stream's ``image`` messages. ``GET /api/sensors/NAME/image`` encodes in a worker thread as well
(:func:`encode_png`, :func:`encode_jpeg_bytes`), never in the loop thread nor on the event loop.
"""

from __future__ import annotations

import base64
import io
import json
import threading
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from simrun.serve.loop import Subscriber

#: JPEG quality of camera images (stream and ``?format=jpeg``).
JPEG_QUALITY = 80
#: Image formats a client may ask for.
FORMATS = ("jpeg", "png")


class ImageEncoder:
    """Encodes stream images in its own thread: the loop thread hands over a copy of the pixels and goes on.

    Each camera keeps only its latest frame waiting: when encoding falls behind the frame rate, older frames
    are skipped (a stream carries the latest image, as its mailbox keeps the latest messages).
    """

    def __init__(self) -> None:
        self._waiting: dict[str, tuple[float, np.ndarray[Any, Any], list[Subscriber]]] = {}
        self._ready = threading.Condition()
        self._closed = False
        self._thread = threading.Thread(target=self._main, name="simrun-serve-images", daemon=True)
        self._thread.start()

    def put(self, name: str, time: float, rgb: np.ndarray[Any, Any], subscribers: list[Subscriber]) -> None:
        """Queue camera ``name``'s frame (H, W, 3) u8 taken at simulated ``time`` s for ``subscribers``."""
        with self._ready:
            self._waiting[name] = (time, rgb, subscribers)
            self._ready.notify()

    def close(self) -> None:
        """Stop the thread (frames still waiting are dropped)."""
        with self._ready:
            self._closed = True
            self._ready.notify()
        self._thread.join(10)

    def _main(self) -> None:
        while True:
            with self._ready:
                while not self._waiting and not self._closed:
                    self._ready.wait()
                if self._closed:
                    return
                name, (t, rgb, subscribers) = self._waiting.popitem()
            messages: dict[str, str] = {}
            for sub in subscribers:
                fmt = sub.image_format
                if fmt not in messages:
                    data = encode_jpeg(rgb) if fmt == "jpeg" else base64.b64encode(encode_png(rgb)).decode("ascii")
                    messages[fmt] = json.dumps({"type": "image", "name": name, "time": t, "format": fmt, "data": data})
                sub.push(messages[fmt])


def image_of(reading: Any) -> np.ndarray[Any, Any] | None:
    """The RGB image of a camera reading (a stereo pair: the left eye), else ``None``."""
    rgb = getattr(reading, "rgb", None)
    if rgb is None and getattr(reading, "left", None) is not None:
        rgb = reading.left.rgb
    return rgb if isinstance(rgb, np.ndarray) else None


def encode_jpeg(rgb: np.ndarray[Any, Any], quality: int = JPEG_QUALITY) -> str:
    """An RGB image (H, W, 3) u8 as base64 JPEG text."""
    return base64.b64encode(encode_jpeg_bytes(rgb, quality)).decode("ascii")


def encode_jpeg_bytes(rgb: np.ndarray[Any, Any], quality: int = JPEG_QUALITY) -> bytes:
    """An RGB image (H, W, 3) u8 as JPEG bytes."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb)).save(buffer, format="JPEG", quality=quality)
    return buffer.getvalue()


def encode_png(rgb: np.ndarray[Any, Any]) -> bytes:
    """An RGB image (H, W, 3) u8 as PNG bytes."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb)).save(buffer, format="PNG")
    return buffer.getvalue()
