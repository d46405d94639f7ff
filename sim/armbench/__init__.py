"""armbench: IEC 61131-3 ST compiler, soft PLC and plant simulation for the arm library."""
