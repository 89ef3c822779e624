"""Software-in-the-loop: simulated vehicle and simulated leg board."""
