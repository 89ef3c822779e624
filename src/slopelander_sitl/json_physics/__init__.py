"""slopelander's landing physics behind ArduPilot SITL's external-physics ("JSON") interface."""
