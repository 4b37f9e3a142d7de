"""The pybullet differential-drive rover world of the STNS paper: room, goal, obstacle, sensors, behaviours, rewards, faults."""
