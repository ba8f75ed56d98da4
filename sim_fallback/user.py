"""The simulated user: what a person at the robot would give the controller about the part to open, and nothing else.

A user clicks one pixel well inside the part's front in the first frame (`deploy open-drawer --point U V`): not on
its edge, not on its handle. This reads the world's ground truth (the camera's (body, link) image and the part's
links), so it belongs to evaluation and benchmarks, never to the controller.
"""

from __future__ import annotations

import cv2
import numpy as np

INSIDE_SHARE = 0.5  # the pixel lies at least this share of the front's largest inset from its edge


def user_pixel(links: np.ndarray, body: int, part_link: int, handle_links: tuple[int, ...],
               rng: np.random.Generator) -> tuple[int, int] | None:
    """(u, v) of a pixel a user would click on the part `part_link` of `body` in the (H, W, 2) (body, link) image
    `links`, away from its edge and its handle (`handle_links`, links fixed to the part); drawn with `rng` among the
    pixels at least INSIDE_SHARE of the largest inset deep. None when no pixel of the part is visible."""
    on_body = links[..., 0] == body
    front = on_body & (links[..., 1] == part_link)
    if not front.any():
        return None
    handle = on_body & np.isin(links[..., 1], [link for link in handle_links if link != part_link])
    handle = cv2.dilate(handle.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    inset = cv2.distanceTransform((front & ~handle).astype(np.uint8), cv2.DIST_L2, 5)
    if inset.max() <= 0:
        return None
    rows, cols = np.nonzero(inset >= INSIDE_SHARE * inset.max())
    k = int(rng.integers(len(rows)))
    return int(cols[k]), int(rows[k])
