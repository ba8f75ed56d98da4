import numpy as np
import pytest

from deploy.errors import PerceptionError
from deploy.perception.oracle import OracleSegmenter
from deploy.perception.registry import make_segmenter
from drivers.camera.base import Frame, Intrinsics, SegLabel


def _frame(segmentation):
    intr = Intrinsics.from_fov(4, 3, 60.0)
    return Frame(7, 0.0, np.zeros((3, 4, 3), np.uint8), np.ones((3, 4), np.float32), intr,
                 segmentation=segmentation)


def test_masks_from_labels():
    labels = np.array([[0, 1, 2, 3], [1, 1, 0, 2], [3, 3, 3, 0]], np.uint8)
    seg = OracleSegmenter()
    frame = _frame(labels)
    obj = seg.start(frame, prompt="drawer")
    np.testing.assert_array_equal(obj, (labels == SegLabel.OBJECT) | (labels == SegLabel.HANDLE))
    np.testing.assert_array_equal(seg.track(frame), obj)
    np.testing.assert_array_equal(seg.handle_mask(frame), labels == SegLabel.HANDLE)


def test_no_segmentation_is_an_actionable_error():
    with pytest.raises(PerceptionError, match="frame 7 has no segmentation labels or stored mask.*gdino-sam2"):
        make_segmenter("oracle").track(_frame(None))


def test_a_recordings_stored_mask_is_the_oracle_without_labels():
    frame = _frame(None)
    frame.mask = np.zeros(frame.depth_m.shape, bool)
    frame.mask[2:5, 3:7] = True
    seg = make_segmenter("oracle")
    np.testing.assert_array_equal(seg.start(frame), frame.mask)
    assert seg.handle_mask(frame) is None
