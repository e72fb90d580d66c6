"""Processing a run: frames measured, strains reconstructed, clocks aligned, free decays
identified, the beam simulated from the measured hub angle."""
