"""Small MJCF scenes shared by several test modules."""

#: A 30 cm aluminium plate on the floor and a 2 cm ball 25 cm above it (1 ms steps; the
#: contacts' solref gives a restitution of about 0.6). The ball's first impact is at ~0.2 s.
PLATE_BALL_XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom><text name="mjsound:plate" data="aluminium"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1"/>
    <geom name="plate" type="box" size="0.15 0.15 0.005" pos="0 0 0.005" solref="-1e5 -120"/>
    <body name="ball" pos="0 0 0.25"><freejoint/>
      <geom name="ball" type="sphere" size="0.02" solref="-1e5 -120"/></body>
  </worldbody>
</mujoco>"""
