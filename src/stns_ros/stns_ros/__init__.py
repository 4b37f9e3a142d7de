"""ROS 2 nodes over stns_core and rover_sim: simulator, agent, fault injector, MCAP recording, replay, bring-up."""
