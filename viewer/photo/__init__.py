"""The photo path: a photo's frame, the person's matte, the networks' inference and their refinement,
the face and the gloss, into a scene bundle."""
