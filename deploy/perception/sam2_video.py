"""SAM2 (or EdgeTAM) video tracking in streaming mode: one session, box and point prompts, then one call per new
frame.

The session is opened without a video; frames are added as the camera delivers them. Memory stays
bounded: after each frame, the processed frames and per-frame outputs older than the model's own memory
horizon (its mask memories and object pointers) are dropped; only the prompted frame is kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np

Box = tuple[float, float, float, float]
Point = tuple[float, float]


class StreamingTracker:
    """Tracks the objects prompted by boxes on the first frame (`start`) through every later frame (`track`).

    model / processor: a Sam2VideoModel or EdgeTamVideoModel and its Sam2VideoProcessor (`models.load_tracker`).
    """

    def __init__(self, model: Any, processor: Any):
        self.model = model
        self.processor = processor
        config = model.config
        self.horizon = max(int(config.num_maskmem), int(config.max_object_pointers_in_encoder))
        self.session: Any = None
        self.frame_idx = -1

    def start(self, color: np.ndarray, boxes: dict[int, Box],
              points: dict[int, list[Point]] | None = None) -> dict[int, np.ndarray]:
        """Open a new session on `color` (RGB) with, per object id, a box and/or points on the object (positive
        clicks, pixels (x, y)); the first masks by id."""
        points = points or {}
        if not boxes and not points:
            raise ValueError("StreamingTracker.start needs at least one box or point")
        self.session = self.processor.init_video_session(
            inference_device=self.model.device, dtype=self.model.dtype
        )
        self.frame_idx = 0
        inputs = self.processor(images=color, return_tensors="pt")
        size = inputs["original_sizes"][0]
        ids = list(dict.fromkeys([*boxes, *points]))
        for obj_id in ids:  # one call per object: each has its own kind of prompt
            prompt: dict[str, Any] = {}
            if obj_id in boxes:
                prompt["input_boxes"] = [[list(map(float, boxes[obj_id]))]]
            if obj_id in points:
                clicks = [[float(x), float(y)] for x, y in points[obj_id]]
                prompt["input_points"], prompt["input_labels"] = [[clicks]], [[[1] * len(clicks)]]
            self.processor.add_inputs_to_inference_session(self.session, frame_idx=0, obj_ids=[obj_id],
                                                           original_size=size, **prompt)
        self.session.obj_with_new_inputs = ids  # each call names only its own object: the first frame runs them all
        return self._step(inputs)

    def track(self, color: np.ndarray) -> dict[int, np.ndarray]:
        """The masks of every prompted object on the next frame, by object id."""
        if self.session is None:
            raise RuntimeError("StreamingTracker.track called before start")
        self.frame_idx += 1
        return self._step(self.processor(images=color, return_tensors="pt"))

    def _step(self, inputs: Any) -> dict[int, np.ndarray]:
        import torch

        with torch.inference_mode():
            out = self.model(inference_session=self.session, frame=inputs["pixel_values"][0],
                             frame_idx=self.frame_idx)
        masks = self.processor.post_process_masks(
            [out.pred_masks.float().cpu()], original_sizes=inputs["original_sizes"], binarize=True
        )[0]
        present = (out.object_score_logits.float().cpu().reshape(-1) > 0).numpy()
        self._forget_old_frames()
        return {
            int(obj_id): masks[k, 0].numpy().astype(bool) & bool(present[k])
            for k, obj_id in enumerate(out.object_ids)
        }

    def _forget_old_frames(self) -> None:
        """Drop what the model will never look at again: bounded memory however long the run."""
        session, oldest = self.session, self.frame_idx - self.horizon + 1  # the last `horizon` frames stay
        for idx in [i for i in session.processed_frames if i != self.frame_idx]:
            del session.processed_frames[idx]
        for obj_idx, outputs in session.output_dict_per_obj.items():
            non_cond = outputs["non_cond_frame_outputs"]
            for idx in [i for i in non_cond if i < oldest]:
                del non_cond[idx]
            tracked = session.frames_tracked_per_obj[obj_idx]
            for idx in [i for i in tracked if i < oldest]:
                del tracked[idx]

    @property
    def stored_frames(self) -> int:
        """Frames whose outputs the session holds (bounded by the model's memory horizon + prompts)."""
        if self.session is None:
            return 0
        return max(len(o["cond_frame_outputs"]) + len(o["non_cond_frame_outputs"])
                   for o in self.session.output_dict_per_obj.values())
