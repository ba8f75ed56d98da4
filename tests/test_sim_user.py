"""The simulated user's pixel: inside the part's front, away from its edge and its handle, seeded."""

import numpy as np

from sim_fallback.user import user_pixel


def _image():
    links = np.full((120, 160, 2), -1, np.int32)
    links[10:110, 10:70] = (5, 2)  # the part's front
    links[10:110, 75:150] = (5, 3)  # the neighbouring front of the same body
    links[55:65, 20:60] = (5, 4)  # its handle, a link fixed to the part
    return links


def test_the_pixel_lies_deep_inside_the_part_and_off_its_handle():
    links = _image()
    for seed in range(20):
        u, v = user_pixel(links, 5, 2, (2, 4), np.random.default_rng(seed))
        assert tuple(links[v, u]) == (5, 2)
        assert 12 <= u <= 67 and 12 <= v <= 107  # not at the front's edge
        assert not (50 <= v <= 69 and 16 <= u <= 63)  # not on (or touching) the handle


def test_seeded_and_none_when_the_part_is_not_seen():
    links = _image()
    assert user_pixel(links, 5, 2, (2, 4), np.random.default_rng(1)) == user_pixel(links, 5, 2, (2, 4),
                                                                                  np.random.default_rng(1))
    assert user_pixel(links, 5, 9, (9,), np.random.default_rng(0)) is None
    assert user_pixel(links, 6, 2, (2,), np.random.default_rng(0)) is None
