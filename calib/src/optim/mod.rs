//! Global and local optimisers (ask/tell): direct search, pattern search, annealing, genetic, swarm, CMA-ES.
