"""pyserial URL handlers: ``protocol_sim`` makes ``sim://`` a serial port, ``protocol_zenoh`` ``zenoh://``.

Deliberately empty: pyserial imports this package on every ``serial_for_url``
call once it is in ``serial.protocol_handler_packages``.
"""
