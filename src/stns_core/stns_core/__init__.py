"""The STNS learner: situations, classifier, categorical learning, STN, IPRL/PIA planners, agent, save/load."""
