"""Track-loss criteria, boxes and the device choice."""

import numpy as np
import pytest

from deploy.errors import ConfigError
from deploy.perception.config import perception_config
from deploy.perception.device import choose_device
from deploy.perception.gdino import grounding_text
from deploy.perception.registry import make_segmenter
from deploy.perception.track_health import box_iou, box_of, mask_iou, track_lost


def test_mask_iou_and_boxes():
    a = np.zeros((4, 6), bool)
    b = np.zeros((4, 6), bool)
    a[:, :3] = True
    b[:, 2:4] = True
    assert mask_iou(a, b) == pytest.approx(4 / 16)
    assert mask_iou(np.zeros((2, 2), bool), np.zeros((2, 2), bool)) == 1.0
    assert box_of(b) == (2.0, 0.0, 4.0, 4.0) and box_of(np.zeros((2, 2), bool)) is None
    assert box_iou((0, 0, 2, 2), (1, 0, 3, 2)) == pytest.approx(2 / 6)
    assert box_iou((0, 0, 1, 1), (5, 5, 6, 6)) == 0.0


def test_track_lost_by_area_or_overlap():
    prev = np.zeros((10, 10), bool)
    prev[2:8, 2:8] = True
    assert track_lost(prev, prev, 36, 0.3, 0.3) is None
    small = np.zeros_like(prev)
    small[2:4, 2:4] = True
    assert "below 0.30 x the first mask's 36 px" in track_lost(small, prev, 36, 0.3, 0.3)
    moved = np.roll(prev, 5, axis=1)
    assert "IoU 0.20 with the previous mask" in track_lost(moved, prev, 36, 0.3, 0.3)


def test_device_choice_and_options():
    import torch

    device, dtype = choose_device("auto")
    expected = "cuda" if torch.cuda.is_available() else "mps" if torch.backends.mps.is_available() else "cpu"
    assert device == expected and dtype == (torch.float32 if device == "cpu" else torch.bfloat16)
    assert choose_device("cpu") == ("cpu", torch.float32)
    if not torch.cuda.is_available():
        with pytest.raises(ConfigError, match="device 'cuda' is not available"):
            choose_device("cuda")
    with pytest.raises(ConfigError, match="unknown device 'tpu'"):
        choose_device("tpu")
    with pytest.raises(ConfigError, match="invalid perception option.*box_threshold"):
        perception_config(box_threshold=2.0)
    with pytest.raises(ConfigError, match="unknown segmenter 'sam'"):
        make_segmenter("sam")


def test_grounding_text():
    assert grounding_text("Cabinet") == "cabinet."
    assert grounding_text("cabinet. drawer handle") == "cabinet. drawer handle."
