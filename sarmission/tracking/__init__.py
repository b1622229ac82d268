"""Multi-target tracking in image space and m-of-k lock confirmation."""
