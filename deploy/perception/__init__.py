"""Perception: segmenter backends (`deploy.perception.registry`) that find the object on the first frame and
track it; the handle mask when a backend tells it apart."""
