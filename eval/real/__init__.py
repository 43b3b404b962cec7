"""Jobs on the real cell (or its emulator).

``drillgym run`` (:mod:`.run`) and ``drillgym ft-check`` (:mod:`.ft_check`).
"""
