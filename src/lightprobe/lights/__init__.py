"""Paper 3 (Arbree, Walter & Bala 2005): an environment map as circular area lights plus an ambient remainder; the point-light baselines; hybrid irradiance; the lights JSON file."""
