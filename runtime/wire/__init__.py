"""What crosses a process boundary: the network protocol, the loop's channel, CURVE keys, the
scripting interface's text, and the typed values the loop and the server exchange.
"""
