"""The scene a relit picture is made of: the bundle of maps, its camera and geometry, the ground, the
shadow space, the area lights, the look and the quality presets: the types every stage shares."""
