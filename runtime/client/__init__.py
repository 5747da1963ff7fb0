"""What a client of ``irl serve`` needs: requests and replies over :mod:`runtime.wire`.
"""
