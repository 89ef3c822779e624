"""The landing sequence, one state per module named for it; run by the controller's machine."""
