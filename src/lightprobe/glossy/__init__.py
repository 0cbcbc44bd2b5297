"""Paper 2 (Cabral, Olano & Nemec 1999): isotropic BRDFs, radiance environment maps, reflection-space IBR, GGX prefiltering, and radiance-map sets on disk."""
