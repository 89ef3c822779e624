"""A simulated ArduCopter quad flying the planar landing model, spoken to over MAVLink."""
