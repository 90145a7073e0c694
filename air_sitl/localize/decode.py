"""A frame's JPEG decoded to grey at a reduced size, once for every method fed that frame.

``mapmatch`` and ``vo`` both decode the frame they are given in grey at 1/2 size (libjpeg's DCT
scaling: three times cheaper than full BGR). When one driver feeds the same observation to
several methods (:func:`air_sitl.localize.archive.run_archive_methods`) the second asks for
the same bytes at the same reduction: it gets the first one's image, which no method writes
into (it is read-only). Only the last frame is kept, held with its bytes object, so the
identity test cannot be fooled by a new object at a freed address; the images are those of
decoding alone, so estimates do not change.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

Image = npt.NDArray[np.uint8]
_FLAGS = {
    1: cv2.IMREAD_GRAYSCALE,
    2: cv2.IMREAD_REDUCED_GRAYSCALE_2,
    4: cv2.IMREAD_REDUCED_GRAYSCALE_4,
    8: cv2.IMREAD_REDUCED_GRAYSCALE_8,
}
# (the JPEG's bytes object, reduction, its image): the last decoding. One tuple, replaced
# whole, so threads (online drivers) see a consistent entry.
_last: list[tuple[bytes, int, Image] | None] = [None]


def decode_gray(jpeg: bytes, reduce: int) -> Image:
    """A JPEG decoded to grey at 1/``reduce`` size (1, 2, 4 or 8), read-only; ValueError when
    it does not decode."""
    last = _last[0]
    if last is not None and last[0] is jpeg and last[1] == reduce:
        return last[2]
    img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), _FLAGS[reduce])
    if img is None:
        msg = "not a decodable JPEG"
        raise ValueError(msg)
    image = np.asarray(img, dtype=np.uint8)
    image.flags.writeable = False
    _last[0] = (jpeg, reduce, image)
    return image
