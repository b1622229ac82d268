"""MITE-Net perception: vSTMD motion front-end, TTM-RPN proposals, motion-enhanced crops, head."""
