"""Design the segment magnetisations of scenes/c_shape.toml (run once, offline; the result is committed in the scene):

    python scenes/c_shape/design.py [--iterations N]

1. a least-squares start with seed 003's Cosserat rod (magsoro.rod): per segment a direction and |Br| up to the
   composite's remanence, fitted to the target letter at 20 mT and, lightly weighted, to the letter forming
   gradually at 5, 10 and 15 mT (so MPM and rod follow one branch of equilibria);
2. `magsoro optimize scenes/c_shape.toml --static --target scenes/c_shape/target.toml --vars magnetisation` (L-BFGS,
   gradients by the adjoint of the static solver; Adam with small steps where an L-BFGS line search tries a design
   the static solver cannot solve) from that start, on the MPM scene itself, through the scene's [static] levels;
3. the optimised vectors written into the scene's [[robot.parts]]; a segment the optimiser takes past the
   composite's remanence is set to it and held while the others are optimised again.

Writes scenes/c_shape/target.toml (the optimiser's target file) and runs/design/c_shape/ (optimize's outputs). Takes 10-30
minutes on two shared CPU cores. See magsoro.robots._letters.design.
"""

if __name__ == "__main__":
    import argparse

    from magsoro.robots._letters import design
    from magsoro.robots.c_shape import LETTER

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--iterations", type=int, default=20, help="L-BFGS iterations of magsoro optimize (default 20)")
    p.add_argument("--reuse-start", action="store_true", help="read step 1's result from runs/design/NAME/rod_start.json")
    a = p.parse_args()
    design(LETTER, iterations=a.iterations, reuse_start=a.reuse_start)
