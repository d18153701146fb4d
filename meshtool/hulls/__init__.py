"""The hulls stage: options, convex hulls, CoACD decompositions (in a child process), surface integrals."""
