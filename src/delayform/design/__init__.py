"""Design: the delays (scheduling) and the gains that make a team converge fastest."""
