"""Evaluation: NWD matching, SAR metrics (SSR / FAR / search time), box metrics by size band."""
