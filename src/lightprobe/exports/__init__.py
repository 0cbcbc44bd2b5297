"""What engines load: SH in every engine's convention, the found lights as engine lights, and the environment in engines' own containers."""
