"""Analysis of run files: spectra, time-frequency transforms and the Synchronization Index (paper §2.2)."""
