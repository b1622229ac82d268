"""Training of the MITE-Net head: datasets, GT jittering, NWD assignment, hard negatives, losses."""
