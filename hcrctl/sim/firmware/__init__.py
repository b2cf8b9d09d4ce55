"""``hcrctl sim --firmware``: a real firmware on an emulated ATmega328P, in the simulated world.

``build`` turns a sketch into an ELF (avr-gcc and the Arduino core, cached);
``harness`` runs it under libsimavr in a small C program held to wall time;
``robot`` wires the chip's pins to the simulator's body (motors, bumpers, IR,
light); ``serve`` puts UART0 on a pty; ``pins`` maps pins to parts;
``toolchain`` finds the Debian packages and keeps the build cache.
Standard library only, as the rest of the simulator.
"""
