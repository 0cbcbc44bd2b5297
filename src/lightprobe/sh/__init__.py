"""Paper 1 (Ramamoorthi & Hanrahan 2001): the real SH basis, projection and rotation, irradiance environment maps (E = nᵀMn), lighting design, and the SH JSON file."""
