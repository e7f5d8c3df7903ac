"""Perception: detections and masks from RGB-D frames, and their map-frame positions."""
