"""The lighting side: environment maps, their area lights (median cut, the fit, the cache), the
lights the user places, spherical harmonics, and where a map's lights come from."""
