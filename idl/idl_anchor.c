/* The generated artms.c is compiled into this library (idlc_generate adds it). */
