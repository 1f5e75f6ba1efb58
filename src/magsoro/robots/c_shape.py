"""Seed 003's "C"-shaped robot (Note S1, Figs S6-S7): a straight strip of ten magnetised segments bends into a
C as a uniform field rises to 20 mT; MPM (2D, static solver) against seed 003's Cosserat rod and the designed
letter. The shared code is :mod:`magsoro.robots._letters`."""

from magsoro.robots._letters import Letter, make_robot

LETTER = Letter(
    name="c_shape",
    letter="C",
    # a straight 3 mm arm, a half circle over 14 mm, a straight 3 mm arm (our reading of the letter)
    pieces=((0.15, 0.0), (0.7, 180.0), (0.15, 0.0)),
    title='"C"-shaped robot (designed magnetisation profile)',
    sentence=("A 20 x 0.5 mm Dragon Skin 10 + NdFeB strip with ten segments, magnetised as designed by magsoro "
              "optimize, bends into a C as a uniform field rises to 20 mT; the 2D MPM strip (static solver) and "
              "seed 003's Cosserat rod form the same letter."),
)

ROBOT = make_robot(LETTER)
