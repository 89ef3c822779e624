"""The simulated ArduCopter that runs slopelander's on-board script (``scripting``) in Lua 5.3."""
