"""The plate path: a background photo the person is put into, its camera read from its
file, its light estimated as an HDR map (and from there area lights, as for any map)."""
