"""Hardware-in-the-loop-style loop over a pseudo-terminal."""
