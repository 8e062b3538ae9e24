"""The HF patch network: model, state, contact, integrators and engines behind one run loop, run files."""
