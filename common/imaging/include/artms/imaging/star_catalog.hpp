// star_catalog (to be written)
