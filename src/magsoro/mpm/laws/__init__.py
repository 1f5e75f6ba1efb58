"""The constitutive laws: elastic (the registry of hyperelastic laws and their Warp functions), viscous (Prony
relaxation), eigenstrain (stimulus-driven stress-free shapes) and the Prony tables' closed forms."""
