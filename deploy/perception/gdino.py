"""Grounding DINO: text prompt -> boxes, best first (the post-processor does not sort them)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Detection:
    """One detected box in pixels (x0, y0, x1, y1), its score in [0, 1] and the matched words."""

    box: tuple[float, float, float, float]
    score: float
    label: str


def grounding_text(prompt: str) -> str:
    """Grounding DINO's text format: lower case, every phrase ending with a period ("cabinet.")."""
    phrases = [p.strip().lower() for p in prompt.split(".") if p.strip()]
    return " ".join(f"{p}." for p in phrases)


class GroundingDinoDetector:
    """Zero-shot detector on a loaded (model, processor) pair (see `models.load_detector`)."""

    def __init__(self, model: Any, processor: Any, box_threshold: float = 0.25, text_threshold: float = 0.3):
        self.model = model
        self.processor = processor
        self.box_threshold = box_threshold
        self.text_threshold = text_threshold

    def detect(self, color: np.ndarray, prompt: str, within: tuple[float, float, float, float] | None = None
               ) -> list[Detection]:
        """Boxes of `prompt` on the RGB image `color`, highest score first; only those whose centre lies
        `within` a box when one is given."""
        import torch

        h, w = color.shape[:2]
        inputs = self.processor(images=color, text=grounding_text(prompt), return_tensors="pt")
        inputs = inputs.to(self.model.device)
        if "pixel_values" in inputs:
            inputs["pixel_values"] = inputs["pixel_values"].to(self.model.dtype)
        with torch.inference_mode():
            outputs = self.model(**inputs)
        result = self.processor.post_process_grounded_object_detection(
            outputs, inputs["input_ids"], threshold=self.box_threshold, text_threshold=self.text_threshold,
            target_sizes=[(h, w)],
        )[0]
        if result["scores"].numel() == 0:
            return []
        labels = result["text_labels"] if "text_labels" in result else result["labels"]
        detections = [
            Detection(tuple(float(v) for v in box), float(score), str(label))
            for box, score, label in zip(result["boxes"].float().cpu().numpy(), result["scores"].float().cpu(),
                                         labels, strict=True)
        ]
        if within is not None:
            x0, y0, x1, y1 = within
            detections = [d for d in detections
                          if x0 <= (d.box[0] + d.box[2]) / 2 <= x1 and y0 <= (d.box[1] + d.box[3]) / 2 <= y1]
        return sorted(detections, key=lambda d: d.score, reverse=True)
